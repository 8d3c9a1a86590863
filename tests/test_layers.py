"""The package's import contracts (pyproject.toml, ``[tool.importlinter]``): its layers and no import cycle,
checked by import-linter, the same ``lint-imports`` that ``make test`` runs, imports inside functions included."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def _lint_imports(root: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` on the package under ``root`` with the contract of ``root/pyproject.toml``."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache", "--no-logo"],
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


def _copy(tmp_path: Path) -> Path:
    """A copy of the package and its contracts under ``tmp_path``."""
    shutil.copytree(ROOT / "lerobot_pnp", tmp_path / "lerobot_pnp", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    return tmp_path / "lerobot_pnp"


def _add(module: Path, code: str) -> None:
    module.write_text(module.read_text() + "\n\n" + code + "\n")


def test_no_module_imports_a_layer_above_its_own_and_no_imports_go_round():
    proc = _lint_imports(ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "layers KEPT" in proc.stdout and "no cycles KEPT" in proc.stdout, proc.stdout


def test_an_upward_import_breaks_the_layers(tmp_path):
    """A copy of the package whose leaf ``robot`` imports the command line (inside a function) fails the check,
    naming the import."""
    package = _copy(tmp_path)
    _add(package / "robot.py", "def _upward():\n    from lerobot_pnp import cli  # noqa: F401")
    proc = _lint_imports(tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "layers BROKEN" in proc.stdout, proc.stdout
    assert "lerobot_pnp.robot is not allowed to import lerobot_pnp.cli" in proc.stdout, proc.stdout


def test_two_modules_of_one_package_importing_each_other_break_the_no_cycles_contract(tmp_path):
    """``evaluation.stats`` and ``evaluation.records`` share a layer: importing each other (one of them inside a
    function) keeps the layers but is a cycle."""
    package = _copy(tmp_path)
    _add(package / "evaluation" / "stats.py", "from lerobot_pnp.evaluation import records  # noqa: E402, F401")
    _add(
        package / "evaluation" / "records.py",
        "def _back():\n    from lerobot_pnp.evaluation import stats  # noqa: F401",
    )
    proc = _lint_imports(tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "layers KEPT" in proc.stdout and "no cycles BROKEN" in proc.stdout, proc.stdout
    assert "No cycles are allowed in lerobot_pnp.evaluation." in proc.stdout, proc.stdout
