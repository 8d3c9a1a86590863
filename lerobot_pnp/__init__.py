"""lerobot_pnp: Baxter pick-and-place in MuJoCo, a scripted FSM expert and an LSTM task planner for LeRobot.

Importing the package registers the gymnasium env ``lerobot_pnp/BaxterPnP-v0`` and nothing heavier (no torch,
LeRobot or MuJoCo) and sets no environment variable. LeRobot's env config ``baxter_pnp`` and policy ``pnp_lstm``
register with their modules; LeRobot's plugin discovery runs ``registration.register_plugin`` (see
``lerobot_policy_pnp_lstm``), our own entry points ``registration.register_all``.
"""

from lerobot_pnp.registration import register_gym
from lerobot_pnp.version import __version__ as __version__  # the one place it is set: version.py

register_gym()
