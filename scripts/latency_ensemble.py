"""Is the recovering planner's shortfall at two steps of latency particular to each training seed?

Training seeds of the same recipe score 84.5-92.5 % on ``heldout_latency_2``. If each seed failed its own
episodes, a planner averaging several seeds' networks would fail fewer. This runs protocol checkpoints
(``outputs/RUN/train_done.json`` from ``scripts/heldout_protocol_eval.py``, trained on the same demonstrations,
so one pre-processor serves all) as one planner: every network steps its own LSTM state on the same
observations, and the planner acts on the mean of their actions (and of their subtask probabilities, for the
logs). The first checkpoint's observation gate holds the mean command. The study's evaluator, 10 envs at a time.

    python scripts/latency_ensemble.py s0,s1,s2 heldout_latency_2,heldout_latency_jitter --seed 10000000 --n_episodes 200
"""

from __future__ import annotations

import argparse

import protocol_runs  # scripts/: the protocol runs on disk
import torch

from lerobot_pnp.evaluation.checkpoints import load_policy
from lerobot_pnp.evaluation.closed_loop import eval_lerobot_policy
from lerobot_pnp.evaluation.stats import Rate
from lerobot_pnp.policy.recovering import RecoveringPlanner
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.suites import SUITES


def averaged(members: list[RecoveringPlanner]):
    """A ``RecoveringPlanner.step`` over several networks: their LSTM states side by side, the heads averaged."""

    def step(x, state):
        outs, memory = [], []
        for i, member in enumerate(members):
            out, (h, c) = RecoveringPlanner.step(member, x, None if state is None else state[2 * i : 2 * i + 2])
            outs.append(out)
            memory += [h, c]
        mean = {k: torch.stack([o[k] for o in outs]).mean(0) for k in ("action", "phase_logits")}
        mean["subtask_logits"] = torch.stack([o["subtask_logits"].softmax(-1) for o in outs]).mean(0).log()
        return mean, tuple(memory)

    return step


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", help="comma-separated protocol runs, e.g. s0,s1,s2")
    p.add_argument("suites", help="comma-separated suites")
    p.add_argument("--seed", type=int, default=10_000_000)
    p.add_argument("--n_episodes", type=int, default=200)
    args = p.parse_args()
    runs = args.runs.split(",")
    checkpoints = [protocol_runs.checkpoint(r) for r in runs]
    for suite in args.suites.split(","):
        cfg = SUITES[suite].env_configs(BaxterPnPEnvConfig.from_source(str(protocol_runs.TASK_ROOT)))[0]
        loaded = [load_policy(c, env_cfg=cfg) for c in checkpoints]
        host = loaded[0]
        host.policy.model.step = averaged([lp.policy.model for lp in loaded])
        host.policy.reset()
        records = eval_lerobot_policy(
            host.policy, host.preprocessor, host.postprocessor, cfg, args.n_episodes, args.seed, 10
        )
        rate = Rate.of([r.success for r in records])
        print(f"{'+'.join(runs)} {suite}: {rate.successes}/{rate.n} = {rate}", flush=True)


if __name__ == "__main__":
    main()
