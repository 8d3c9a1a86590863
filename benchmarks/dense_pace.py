"""The dense expert's pace: how many control steps (20 fps) it takes per keyframe, and its longest episodes
against the dense budget (``env_config.DENSE_SECONDS_PER_KEYFRAME``).

A dense-control method (ACT) gets the keyframe methods' budget converted to control steps. The fair rate is
the pace of the demonstrator it imitates: the scripted expert run in dense mode on the same seeds as in keyframe
mode, so that each episode's keyframes and dense steps are counted on the same draws. The check that matters:
the dense expert's longest episode on every suite stays inside the dense budget, as its keyframe episodes stay
inside the keyframe budget.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/dense_pace.py --preset paper --n_episodes 100 \
        --suites nominal,grasp_miss,drop,displace,random_place,random_yaw --out docs/results/dense_pace_paper.json
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/dense_pace.py --preset full --n_episodes 60 \
        --suites nominal,train_drop,heldout_far_displace,heldout_double_drop,heldout_all_at_once \
        --out docs/results/dense_pace_full.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.sim.expert import run_expert_episode
from lerobot_pnp.sim.suites import get_suites


def episode_steps(cfg: BaxterPnPEnvConfig, seeds: range) -> list[int]:
    """Env steps of the expert's episode on each seed (it raises on a failure; none is expected)."""
    env = make_env(cfg, render_mode=None)
    steps = []
    for seed in seeds:
        run_expert_episode(env, seed)
        steps.append(int(env.unwrapped._step_count))
    env.close()
    return steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--preset", default="paper", help="the task preset (paper | full)")
    parser.add_argument("--suites", default="nominal", help="comma-separated suite names (the study's catalogue)")
    parser.add_argument("--n_episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=100_000, help="first seed (the study's evaluation seeds)")
    parser.add_argument("--out", type=Path, default=None, help="write the table as JSON here")
    args = parser.parse_args()
    seeds = range(args.seed, args.seed + args.n_episodes)
    rows = []
    for suite in get_suites(args.suites.split(",")):
        keyframe = suite.env_configs(BaxterPnPEnvConfig(preset=args.preset))[0]
        dense = keyframe.with_changes(control_mode="dense")
        k, d = np.array(episode_steps(keyframe, seeds)), np.array(episode_steps(dense, seeds))
        row = {
            "suite": suite.name,
            "keyframe_budget": keyframe.episode_length,
            "dense_budget": dense.episode_length,
            "keyframes_max": int(k.max()),
            "dense_steps_mean": round(float(d.mean()), 1),
            "dense_steps_max": int(d.max()),
            "dense_steps_per_keyframe": round(float(d.sum() / k.sum()), 1),
            "dense_max_over_budget": round(float(d.max() / dense.episode_length), 2),
            "keyframe_max_over_budget": round(float(k.max() / keyframe.episode_length), 2),
        }
        rows.append(row)
        print(
            f"{suite.name:24s} keyframes max {row['keyframes_max']:3d} of {row['keyframe_budget']:3d} | dense steps "
            f"mean {row['dense_steps_mean']:6.1f} max {row['dense_steps_max']:4d} of {row['dense_budget']:5d} | "
            f"{row['dense_steps_per_keyframe']:4.1f} steps per keyframe",
            flush=True,
        )
    if args.out:
        args.out.write_text(json.dumps({"preset": args.preset, "episodes": args.n_episodes, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
