"""The package's import layers (pyproject.toml, ``[tool.importlinter]``): checked by import-linter, the same
``lint-imports`` that ``make test`` runs, imports inside functions included."""

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


def test_no_module_imports_a_layer_above_its_own():
    proc = _lint_imports(ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Contracts: 1 kept, 0 broken." in proc.stdout, proc.stdout


def test_an_upward_import_breaks_the_layers(tmp_path):
    """A copy of the package whose leaf ``robot`` imports the command line fails the check, naming the import."""
    shutil.copytree(ROOT / "lerobot_pnp", tmp_path / "lerobot_pnp", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    robot = tmp_path / "lerobot_pnp" / "robot.py"
    robot.write_text(robot.read_text() + "\n\ndef _upward():\n    from lerobot_pnp import cli  # noqa: F401\n")
    proc = _lint_imports(tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "lerobot_pnp.robot is not allowed to import lerobot_pnp.cli" in proc.stdout, proc.stdout
    assert "Contracts: 0 kept, 1 broken." in proc.stdout, proc.stdout
