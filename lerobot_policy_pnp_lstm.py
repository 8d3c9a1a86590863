"""Discovery shim: LeRobot imports plugins by distribution name; this registers everything in lerobot_pnp."""

from lerobot_pnp.registration import register_all

register_all()
