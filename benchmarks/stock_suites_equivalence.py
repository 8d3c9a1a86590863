"""Stock multi-suite evaluation against the study's evaluator, episode by episode, with outcomes that vary.

The policy is the study's lookup table over expert demonstrations of the paper's task (a ``PreTrainedPolicy``
that succeeds where the replay of the nearest start works and fails where a disturbance moves the cube), so the
check is not a run of all-failures (on the ``full`` task it fails every episode). Side one is what ``lerobot-eval --env.task=<suites>`` runs: the env config's
``create_envs`` handed to stock ``eval_policy_all``, every suite from the same start seed (no videos here: they
do not change an outcome). Side two is the study's evaluator (``eval_lerobot_policy``) on each suite's env config.
It writes each suite's successes on both sides and the suites where they differ (none expected).

    OMP_NUM_THREADS=1 MUJOCO_GL=egl python benchmarks/stock_suites_equivalence.py [--task heldout] \\
        [--n_episodes 100] [--demos 100] [--out stock_suites_equivalence.json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

SEED = 100_000  # the study's first evaluation seed; the demonstrations use seeds 0.. (disjoint)


def lookup_table(demos: int):
    """The lookup table over ``demos`` expert episodes of the paper's task (seeds 0..)."""
    from lerobot_pnp.errors import PnPError
    from lerobot_pnp.report.adapters import Episodes
    from lerobot_pnp.report.baselines import LookupTablePolicy
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
    from lerobot_pnp.sim.expert import run_expert_episode

    env = make_env(BaxterPnPEnvConfig(preset="paper"), render_mode=None)
    episodes = []
    for seed in range(demos):
        try:
            episodes.append(run_expert_episode(env, seed))
        except PnPError:  # an expert failure is not a demonstration
            continue
    env.close()
    starts = np.stack([e.env_states[0] for e in episodes])
    return LookupTablePolicy(Episodes(np.arange(len(episodes)), starts, [e.actions for e in episodes]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--task", default="heldout")
    ap.add_argument("--n_episodes", type=int, default=100)
    ap.add_argument("--demos", type=int, default=100)
    ap.add_argument("--batch", type=int, default=50)
    ap.add_argument("--out", type=Path, default=Path("stock_suites_equivalence.json"))
    args = ap.parse_args()
    import torch
    from lerobot.envs.factory import make_env_pre_post_processors
    from lerobot.scripts.lerobot_eval import eval_policy_all

    from lerobot_pnp.evaluation.closed_loop import eval_lerobot_policy
    from lerobot_pnp.integration.registration import register_all
    from lerobot_pnp.report.baselines import identity_processors
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.sim.stock_suites import suite_configs

    register_all()
    torch.set_num_threads(1)
    policy, (pre, post) = lookup_table(args.demos), identity_processors()
    cfg = BaxterPnPEnvConfig(preset="paper", task=args.task)
    t = time.perf_counter()
    env_pre, env_post = make_env_pre_post_processors(cfg, policy.config)
    with torch.no_grad():
        info = eval_policy_all(cfg.create_envs(n_envs=args.batch), policy, env_pre, env_post, pre, post,
                               args.n_episodes, start_seed=SEED)  # fmt: skip
    stock_s = time.perf_counter() - t
    stock = {task["task_group"]: task["metrics"]["successes"] for task in info["per_task"]}
    t, study = time.perf_counter(), {}
    for suite, env_cfg in suite_configs(cfg).items():
        records = eval_lerobot_policy(policy, pre, post, env_cfg, args.n_episodes, SEED, args.batch)
        study[suite] = [r.success for r in records]
    study_s = time.perf_counter() - t
    differ = sorted(s for s in study if stock.get(s) != study[s])
    result = {"task": args.task, "episodes_per_suite": args.n_episodes, "demos": len(policy.table),
              "stock_s": stock_s, "study_s": study_s, "outcomes_differ": differ,
              "success": {s: {"stock": sum(stock[s]), "study": sum(v), "n": len(v)} for s, v in study.items()}}  # fmt: skip
    args.out.write_text(json.dumps(result, indent=2))
    for s, v in result["success"].items():
        print(f"{s:<26} stock {v['stock']:>4}/{v['n']}  study {v['study']:>4}/{v['n']}")
    print(f"stock {stock_s:.0f} s, study {study_s:.0f} s; outcomes differ on {differ or 'no suite'}")
    if differ:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
