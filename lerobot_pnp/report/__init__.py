"""The reproduction study: methods x evaluation suites x seeds -> ``report.md`` with intervals and plots.

One job per module: ``methods`` (what is compared; ``recipes``: the recovering recipe and the DAgger / DART
schedules, ``builders``: how each method is trained and evaluated, ``training``: a training's key and the keyed
training, ``method_spec``: the ``Method`` and ``TrainContext`` types they share), ``baselines`` (the
open-loop lookup table), ``adapters`` (the only calls into the dataset generator and the fast trainer),
``config`` (``StudyConfig`` and its presets), ``layout`` (every path of a study), ``run`` (the stages, cached
on disk and resumable; ``schedule``: its jobs and their pool, ``job``: what one job does, ``cluster``: the same
jobs as SLURM jobs, ``slurm``: their options, ``cross_check``: the `lerobot-eval` cross-check), ``figures``,
``claims``, ``markdown`` and ``preamble`` (the text; ``preamble``: its opening and Methods section), ``writer`` (``report.md`` and ``summary.json``). Suites, statistics
and results (pooled rates, paired comparisons, verdicts) and their plots live in ``lerobot_pnp.evaluation``, the
evaluators in ``lerobot_pnp.closed_loop``.
"""
