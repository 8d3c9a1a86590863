"""The end-to-end job (the README's main command, ``make demo``): data -> training -> evaluation -> report.

1. Generate the paper's dataset: 1400 expert episodes of 10 keyframes, split 80/20.
2. Train the paper-faithful clocked two-LSTM planner with the fast trainer, once per training seed.
3. Evaluate it, the open-loop lookup-table baseline and the expert on the same seeded episodes with stock
   LeRobot ``eval_policy`` (in process), nominal and under perturbations.
4. Write ``report.md`` (success with 95 % Wilson intervals, paired comparisons, failures by cause and phase),
   its figures and ``summary.json``.

``--quick`` is the CI-sized variant, ``--full`` the whole study (``lerobot_pnp.report.run``). Every stage is
reused when its record matches, so the same command run again after an interrupt resumes where it stopped
(``--fresh`` deletes what the study wrote and starts over). The output folder is the study's to write only where
it holds nothing else of the same name (``lerobot_pnp.report.folder``).
"""

from __future__ import annotations

from dataclasses import dataclass

from lerobot_pnp.report.cli_eval import EvalSpec, run_eval  # noqa: F401  (the lerobot-eval CLI runner)
from lerobot_pnp.report.run import StudyConfig, run_study


@dataclass
class DemoConfig(StudyConfig):
    """``lerobot-pnp demo``: the study with the ``demo`` preset by default (see ``StudyConfig``)."""


def run_demo(cfg: StudyConfig) -> dict:
    return run_study(cfg)
