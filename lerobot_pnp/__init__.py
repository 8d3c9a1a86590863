"""lerobot_pnp: Baxter pick-and-place in MuJoCo, a scripted FSM expert and an LSTM task planner for LeRobot.

Importing the package registers, in this one place: the gymnasium env ``lerobot_pnp/BaxterPnP-v0``, the
LeRobot env config ``baxter_pnp`` and the LeRobot policy ``pnp_lstm``.
"""

from lerobot_pnp.registration import register_all

__version__ = "0.1.0"

register_all()
