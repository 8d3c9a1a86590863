"""MJCF assets of the Baxter pick-and-place scene (installed as ``lerobot_pnp.assets``)."""
