"""The reproduction study: methods x evaluation suites x seeds -> ``report.md`` with intervals and plots.

One job per module: ``stats`` (intervals, paired tests), ``suites`` (named evaluation suites as env-config
changes), ``methods`` (what is compared: how each is trained and evaluated), ``evaluation`` (stock LeRobot
``eval_policy`` on the env, per-episode records), ``baselines`` (the open-loop lookup table),
``adapters`` (the only calls into the dataset generator and the fast trainer), ``plots``, ``writer`` (the
markdown) and ``run`` (the stages, cached on disk and resumable).
"""
