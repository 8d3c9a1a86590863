"""Discovery shim: LeRobot imports plugins by distribution name; this registers everything in lerobot_pnp."""

import lerobot_pnp  # noqa: F401  (registration happens on import)
