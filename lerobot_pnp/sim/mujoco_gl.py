"""MuJoCo's rendering backend (``MUJOCO_GL``) for our simulator: a leaf, so every module that imports MuJoCo, or
makes an env whose workers will, sets the default first."""

from __future__ import annotations

import os
import platform
import sys

from lerobot_pnp.errors import ConfigError

# the values MuJoCo's GL context accepts for MUJOCO_GL, per system (it raises a bare RuntimeError when imported
# with another, from inside ``import mujoco``)
_ANY = ("", "enable", "enabled", "on", "true", "1", "glfw", "disable", "disabled", "off", "false", "0")
_BY_SYSTEM = {"Linux": ("egl", "osmesa", "glx"), "Windows": ("wgl",), "Darwin": ("cgl",)}


def default_mujoco_gl() -> None:
    """Headless EGL rendering for our simulator, set before MuJoCo is imported: only on Linux (MuJoCo refuses
    ``egl`` elsewhere), never over a value the user set, and not once MuJoCo is loaded (it reads the variable
    when imported, so setting it later would only mislead child processes)."""
    if sys.platform.startswith("linux") and "MUJOCO_GL" not in os.environ and "mujoco" not in sys.modules:
        os.environ["MUJOCO_GL"] = "egl"


def check_mujoco_gl() -> None:
    """Refuse, in one line that names the valid choices, a ``MUJOCO_GL`` that MuJoCo would reject when imported."""
    value = os.environ.get("MUJOCO_GL", "").lower().strip()
    system = _BY_SYSTEM.get(platform.system(), ())
    if value not in _ANY + system:
        choices = ", ".join(system + ("glfw", "disable"))
        raise ConfigError(
            f"MUJOCO_GL={os.environ['MUJOCO_GL']!r} is not a MuJoCo rendering backend: use one of {choices}"
        )
