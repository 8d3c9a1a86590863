# Two entry points do all the set-up on a fresh machine (see README):
#   make demo   the end-to-end job: generate expert data, train the LSTM planner, evaluate it closed loop; beside
#               it the recovering planner on the full task, on a recovery suite and two held-out ones
#   make test   ruff, the import layers (import-linter), the test suite and the strict documentation build (what CI runs)
#   make study  the whole study behind docs/results/: the paper task and the held-out-disturbance protocol
#               on the full task (every method, 3 training seeds; resumable; its measured cost: README)
#   make docs   the documentation site into site/
#   make lock   requirements.lock anew from pyproject.toml (keeps its pins; LOCK_FLAGS=--upgrade moves them)
# Python 3.12 comes from pyenv when present (LeRobot 0.6 needs >= 3.12), else python3.12 on PATH.
# The install: uv (pinned, from pip, into the venv) installs requirements.lock, the versions CI tests (the package's
# dependencies and the test extra, for every platform), then the package itself in editable mode. uv reads PyPI
# and its own UV_* settings, not pip's configuration.
PYTHON ?= $(shell p=$$(pyenv prefix 3.12.1 2>/dev/null) && echo $$p/bin/python || command -v python3.12)
VENV := .venv
STAMP := $(VENV)/.installed
LOCK := requirements.lock
UV := $(VENV)/bin/uv
UV_VERSION := 0.13.10
export OMP_NUM_THREADS ?= 1
export MUJOCO_GL ?= egl
export HF_HUB_OFFLINE ?= 1

.PHONY: demo test study install lock docs clean

$(UV):
	@test -n "$(PYTHON)" || { echo "Python 3.12 not found (pyenv install 3.12.1, or set PYTHON=...)"; exit 1; }
	test -x $(VENV)/bin/python || $(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install -q uv==$(UV_VERSION)

# exactly the lock's versions (--no-deps); the check then fails on a dependency the lock lacks (a stale lock).
# --compile-bytecode: the dependencies' .pyc files are written once here (uv writes none by default), so that no
# later process compiles torch and LeRobot again where PYTHONDONTWRITEBYTECODE is set
$(STAMP): pyproject.toml $(LOCK) | $(UV)
	@command -v ffmpeg >/dev/null || { command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ] && \
		(apt-get update -qq && apt-get install -y -qq ffmpeg >/dev/null) || echo "note: ffmpeg not installed (video datasets fall back to PyAV)"; }
	$(UV) pip install -q --compile-bytecode --python $(VENV)/bin/python --no-deps -r $(LOCK) -e .
	@$(UV) pip check -q --python $(VENV)/bin/python || { echo "$(LOCK) misses a dependency of pyproject.toml: make lock"; exit 1; }
	touch $(STAMP)

install: $(STAMP)

LOCK_FLAGS ?=
lock: | $(UV)
	$(UV) pip compile -q pyproject.toml --extra test --universal --python-version 3.12 --custom-compile-command "make lock" $(LOCK_FLAGS) -o $(LOCK)

# each runs its two studies in one process pool (--alongside): the second's jobs fill the cores the first's leave idle
demo: $(STAMP)
	$(VENV)/bin/lerobot-pnp demo --config_path configs/demo.json --alongside configs/demo_recovery.json

study: $(STAMP)
	$(VENV)/bin/lerobot-pnp report --config_path configs/report_full.json --alongside configs/report_heldout.json

test: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/lint-imports  # the layers of pyproject.toml: no module imports a layer above its own
	$(VENV)/bin/python -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder -m ""  # every test, the slow end-to-end ones too; both cores; a file on one worker, long files first (tests/conftest.py)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict  # a page off the nav, a broken link or anchor fails (--quiet would hide them from strict mode)

# the documentation site from docs/ (mkdocs.yml) into site/: open site/index.html, no server needed
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

clean:
	rm -rf $(VENV) outputs build site *.egg-info .import_linter_cache
