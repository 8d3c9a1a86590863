"""Discovery shim: LeRobot imports plugins by distribution name, in every ``lerobot-*`` process; this registers
the plugin cheaply and scoped (``lerobot_pnp.registration.register_plugin``)."""

from lerobot_pnp.registration import register_plugin

register_plugin()
