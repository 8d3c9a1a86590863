"""MuJoCo's rendering backend (``MUJOCO_GL``) for our simulator: a leaf, so every module that imports MuJoCo, or
makes an env whose workers will, sets the default first."""

from __future__ import annotations

import os
import sys


def default_mujoco_gl() -> None:
    """Headless EGL rendering for our simulator, set before MuJoCo is imported: only on Linux (MuJoCo refuses
    ``egl`` elsewhere), never over a value the user set, and not once MuJoCo is loaded (it reads the variable
    when imported, so setting it later would only mislead child processes)."""
    if sys.platform.startswith("linux") and "MUJOCO_GL" not in os.environ and "mujoco" not in sys.modules:
        os.environ["MUJOCO_GL"] = "egl"
