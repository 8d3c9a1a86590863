"""The LeRobot integration: what makes stock ``lerobot-*`` scripts run this plugin's env, policy and data.

The one way in is ``registration``: ``register_plugin`` (what LeRobot's plugin discovery runs, through the shim
``lerobot_policy_pnp_lstm``: cheap and scoped to runs that are ours) and ``register_all`` (our own entry points:
both configs at once). The rest are the hooks it installs: ``stock_cli`` (is this stock command line ours?),
``stock_errors`` (the one-line error hook), ``stock_train`` and ``stock_checkpoints`` (``lerobot-train``),
``stock_eval`` (``lerobot-eval``) and ``recorded_task`` (the task recorded with a ``pnp_lstm`` checkpoint).

This ``__init__`` imports nothing, so importing the package (which registers the gymnasium id through
``registration.register_gym``) loads only ``registration``.
"""
