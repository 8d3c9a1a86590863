# Two entry points do all the set-up on a fresh machine (see README):
#   make demo   the end-to-end job: generate expert data, train the LSTM planner, evaluate it closed loop; beside
#               it the recovering planner on the full task, on a recovery suite and two held-out ones
#   make test   ruff, the test suite and the strict documentation build (what CI runs)
#   make study  the whole study behind docs/results/: the paper task and the held-out-disturbance protocol
#               on the full task (every method, 3 training seeds; resumable; its measured cost: README)
#   make docs   the documentation site into site/
# Python 3.12 comes from pyenv when present (LeRobot 0.6 needs >= 3.12), else python3.12 on PATH.
PYTHON ?= $(shell p=$$(pyenv prefix 3.12.1 2>/dev/null) && echo $$p/bin/python || command -v python3.12)
VENV := .venv
STAMP := $(VENV)/.installed
export OMP_NUM_THREADS ?= 1
export MUJOCO_GL ?= egl
export HF_HUB_OFFLINE ?= 1

.PHONY: demo test study install docs clean

$(STAMP): pyproject.toml
	@test -n "$(PYTHON)" || { echo "Python 3.12 not found (pyenv install 3.12.1, or set PYTHON=...)"; exit 1; }
	@command -v ffmpeg >/dev/null || { command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ] && \
		(apt-get update -qq && apt-get install -y -qq ffmpeg >/dev/null) || echo "note: ffmpeg not installed (video datasets fall back to PyAV)"; }
	test -x $(VENV)/bin/python || $(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

# each runs its two studies in one process pool (--alongside): the second's jobs fill the cores the first's leave idle
demo: $(STAMP)
	$(VENV)/bin/lerobot-pnp demo --config_path configs/demo.json --alongside configs/demo_recovery.json

study: $(STAMP)
	$(VENV)/bin/lerobot-pnp report --config_path configs/report_full.json --alongside configs/report_heldout.json

test: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/python -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder -m ""  # every test, the slow end-to-end ones too; both cores; a file on one worker, long files first (tests/conftest.py)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --quiet  # a page off the nav, a broken link or anchor fails

# the documentation site from docs/ (mkdocs.yml) into site/: open site/index.html, no server needed
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

clean:
	rm -rf $(VENV) outputs build site *.egg-info
