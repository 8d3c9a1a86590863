"""Discovery shim: LeRobot imports plugins by distribution name, in every ``lerobot-*`` process; this registers
the plugin cheaply and scoped (``lerobot_pnp.integration.registration.register_plugin``)."""

from lerobot_pnp.integration.registration import register_plugin

register_plugin()
