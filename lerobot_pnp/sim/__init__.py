"""The simulated domain: Baxter pick-and-place in MuJoCo, its task, its disturbances and its scripted expert.

Bottom to top: ``ik`` and ``interpolation`` (arm kinematics, joint paths), ``physics`` (the MuJoCo model, stepping,
rendering; ``mujoco_gl`` picks the rendering backend), ``disturbances`` and ``task`` (one seeded episode's
scene, its perturbations and success), ``env_validation`` and ``recorded_files`` (the env config's checks and
the task recorded in a dataset or checkpoint), ``suites`` (the catalogue of evaluation suites: named changes to
a training task) and ``stock_suites`` (those suites as stock ``lerobot-eval`` tasks), ``env_config`` (LeRobot's
``--env.type=baxter_pnp``), ``env`` (the gymnasium env) and ``expert`` (the scripted FSM expert).

Nothing here loads a policy, writes a dataset or evaluates one: those layers (``policy`` below, ``dataset`` and
``evaluation`` above) are outside. Modules are imported by name; this ``__init__`` imports nothing.
"""
