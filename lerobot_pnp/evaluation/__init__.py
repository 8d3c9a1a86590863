"""Evaluation shared by the study (``report``), DAgger (``dagger``), the viewer (``viz``) and the benchmarks.

One of each concept, so a name means one thing everywhere:

* ``suites``: the one catalogue of evaluation suites (named changes to a training task; DAgger's
  every-perturbation-off suites are its ``quiet*`` entries) and the held-out protocol's axes;
* ``stats``: the one Wilson interval (``Rate``), the sign test and paired comparisons;
* ``records``: ``EpisodeRecord`` (what one evaluation episode ended with) and its counts / JSON;
* ``checkpoints``: the one strict checkpoint loader (``load_policy``) and its feature / value checks;
* ``results``: the study's pooled rates, paired comparisons and held-out axis verdicts; ``plots``: their figures;
* ``compare`` and ``leaderboard``: the same over stock ``eval_info.json`` files.

The evaluators (one seeded episode of a loaded policy, ``run_episode``, the viewer's and DAgger's; the serial
evaluator built on it; stock LeRobot ``eval_policy`` with per-episode records, the study's) run the simulator:
they are ``lerobot_pnp.closed_loop``, above the env config, which checks ``--env.task`` against ``suites``.

Modules are imported by name (``from lerobot_pnp.evaluation.suites import SUITES``): this ``__init__`` imports
nothing, so a caller of one module loads only what that module needs (the catalogue needs no gymnasium wrapper
and no LeRobot eval script).
"""
