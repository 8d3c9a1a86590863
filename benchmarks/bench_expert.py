"""The scripted expert on every task suite: success over seeded episodes, failures by cause and phase.

Targets: >= 99.5 % on `paper`, on `full` and on each perturbation alone (1000 episodes each); >= 99 % on
every suite of the held-out-disturbance protocol (``sim.suites.HELD_OUT_AXES``, on the `full` training task;
>= 200 episodes each).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_expert.py --n_episodes 1000 --out outputs/bench_expert.json
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_expert.py --n_episodes 200 --suites protocol \
        --out docs/results/bench_expert_protocol.json
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from lerobot_pnp.evaluation.expert_eval import ExpertEvalConfig, evaluate_expert
from lerobot_pnp.evaluation.stats import wilson_interval as wilson
from lerobot_pnp.presets import NARROW_FULL_DISTURBANCES
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.suites import HELD_OUT_AXES, SUITES

BUDGET = {"keyframe_budget": 40}  # room for recoveries
# Whole tasks (env configs), not changes to a training task: a preset each, with its own names.
PRESET_SUITES: dict[str, dict] = {
    "paper": {},
    "full": {"preset": "full"},
    "full, narrow (presets.NARROW_FULL_DISTURBANCES)": {"preset": "full", **NARROW_FULL_DISTURBANCES},
    "nudge 3 cm": {"nudge_max": 0.03},
    "grasp_miss": {"grasp_miss_prob": 1.0, **BUDGET},
    "drop": {"drop_prob": 1.0, **BUDGET},
    "displace": {"displace_prob": 1.0, **BUDGET},
    "obs noise": {"obs_noise_object": 0.005, "obs_noise_joints": 0.01},
    "obs bias 1 cm": {"obs_bias_object": 0.01},
    "latency 1 step": {"obs_latency": 1},
    "random yaw": {"yaw_range": (-math.pi, math.pi), "observe_yaw": True},
    "random place target": {"place_low": (0.50, -0.20), "place_high": (0.70, -0.05), "observe_goal": True},
    "mass/friction": {"mass_range": (0.3, 0.8), "friction_range": (0.7, 1.2)},
    "cube size 4.5-5.5 cm": {"size_range": (0.045, 0.055)},
}


# The held-out protocol's suites, each on the `full` training task (its own perturbations stay on).
PROTOCOL = list(dict.fromkeys(n for axis in HELD_OUT_AXES for n in (*axis.in_distribution, *axis.held_out)))


def env_config(name: str) -> BaxterPnPEnvConfig:
    if name in PROTOCOL:
        return SUITES[name].env_configs(BaxterPnPEnvConfig(preset="full"))[0]
    return BaxterPnPEnvConfig(**PRESET_SUITES[name])


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n_episodes", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--suites", nargs="*", default=list(PRESET_SUITES), help="names, or 'protocol' for all of those"
    )
    parser.add_argument("--out", type=Path, default=Path("outputs/bench_expert.json"))
    args = parser.parse_args(argv)
    results = {}
    names = [n for name in args.suites for n in (PROTOCOL if name == "protocol" else [name])]
    for name in names:
        env = env_config(name)
        res = evaluate_expert(ExpertEvalConfig(n_episodes=args.n_episodes, seed=args.seed, env=env, progress=False))
        k = round(res["success_rate"] * args.n_episodes)
        res["wilson95"] = wilson(k, args.n_episodes)
        results[name] = res
        lo, hi = res["wilson95"]
        print(
            f"{name:<30} {100 * res['success_rate']:6.1f} %  [{100 * lo:5.1f}, {100 * hi:5.1f}]  "
            f"{res['episodes_per_s']:5.1f} ep/s  failures {res['failures_by_cause'] or '-'} "
            f"by phase {res['failures_by_furthest_phase'] or '-'}  recoveries {res['recoveries'] or '-'}",
            flush=True,
        )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2, default=list))
    return results


if __name__ == "__main__":
    main()
