"""Evaluation shared by the study (``report``), DAgger (``dagger``), the viewer (``viz``) and the benchmarks.

One of each concept, so a name means one thing everywhere:

* ``suites``: the one catalogue of evaluation suites (named changes to a training task; DAgger's
  every-perturbation-off suites are its ``quiet*`` entries) and the held-out protocol's axes;
* ``stats``: the one Wilson interval (``Rate``), the sign test and paired comparisons;
* ``records``: ``EpisodeRecord`` (what one evaluation episode ended with) and its counts / JSON;
* ``checkpoints``: the one strict checkpoint loader (``load_policy``) and its feature / value checks;
* ``lerobot_pnp.closed_loop`` (beside this package, above the env config): the evaluators: one seeded episode of a loaded policy (``run_episode``, the viewer's and
  DAgger's), the serial evaluator built on it, and stock LeRobot ``eval_policy`` with per-episode records (the
  study's).

Modules are imported by name (``from lerobot_pnp.evaluation.suites import SUITES``): this ``__init__`` imports
nothing, so a caller of one module loads only what that module needs (the catalogue needs no gymnasium wrapper
and no LeRobot eval script).
"""
