"""Dataset generation throughput and where the time goes.

    .venv/bin/python benchmarks/bench_dataset.py [--episodes 1400] [--dense-episodes 50] [--workers 0]
                                                 [--profile-episodes 100] [--out DIR]

1. The paper's dataset (1400 keyframe episodes) end to end with ``generate`` (workers in parallel, merge,
   verification): wall time and episodes/s. Target: under 60 s on a 2-core machine.
2. Dense episodes (20 fps, state only) the same way.
3. A single-process breakdown of one shard: the share of wall time in MuJoCo physics (mj_step), IK
   (ArmIK.solve/refine/forward, incl. the straight-line path correction), the rest of the expert/env Python,
   and LeRobot's writer (add_frame + save_episode + finalize).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import lerobot_pnp  # noqa: F401
from lerobot_pnp import dataset as D


class _Timer:
    def __init__(self):
        self.total = 0.0
        self.depth = 0

    def wrap(self, fn):
        def wrapped(*args, **kwargs):
            if self.depth:
                return fn(*args, **kwargs)
            self.depth += 1
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.total += time.perf_counter() - t0
                self.depth -= 1

        return wrapped


def breakdown(representation: str, episodes: int, out: Path) -> dict:
    """Run one shard in this process with timers around physics and IK."""
    import mujoco

    from lerobot_pnp.ik import ArmIK

    physics, ik = _Timer(), _Timer()
    saved = (mujoco.mj_step, ArmIK.solve, ArmIK.refine, ArmIK.forward)
    mujoco.mj_step = physics.wrap(mujoco.mj_step)
    ArmIK.solve, ArmIK.refine, ArmIK.forward = (ik.wrap(ArmIK.solve), ik.wrap(ArmIK.refine), ik.wrap(ArmIK.forward))
    cfg = D.GenerateConfig(repo_id="bench/breakdown", representation=representation, num_episodes=episodes)
    D._single_thread()
    D._get_env(cfg.env_kwargs())  # env construction is not counted
    job = {
        "index": 0,
        "start": 0,
        "stop": episodes,
        "seed": 0,
        "num_episodes": episodes,
        "max_retries": 10,
        "repo_id": cfg.repo_id,
        "env_kwargs": cfg.env_kwargs(),
        "dir": str(out / f"breakdown_{representation}"),
    }
    try:
        t0 = time.perf_counter()
        rec = D.build_shard(job)
        wall = time.perf_counter() - t0
    finally:
        mujoco.mj_step, ArmIK.solve, ArmIK.refine, ArmIK.forward = saved
    other_sim = rec["sim_s"] - physics.total - ik.total
    return {
        "representation": representation,
        "episodes": episodes,
        "wall_s": round(wall, 2),
        "ms_per_episode": round(1000 * wall / episodes, 1),
        "share_physics": round(physics.total / wall, 3),
        "share_ik": round(ik.total / wall, 3),
        "share_other_sim": round(other_sim / wall, 3),
        "share_writing": round(rec["write_s"] / wall, 3),
        "write_ms_per_episode": round(1000 * rec["write_s"] / episodes, 1),
    }


def end_to_end(representation: str, episodes: int, workers: int, out: Path) -> dict:
    root = out / f"e2e_{representation}"
    cfg = D.GenerateConfig(
        repo_id=f"bench/{representation}",
        root=str(root),
        representation=representation,
        num_episodes=episodes,
        workers=workers,
        overwrite=root.exists(),
    )
    t0 = time.perf_counter()
    summary = D.generate(cfg)
    wall = time.perf_counter() - t0
    keep = (
        "episodes",
        "frames",
        "shards",
        "workers",
        "generate_wall_s",
        "merge_wall_s",
        "simulate_cpu_s",
        "write_cpu_s",
        "expert_failures",
    )
    return {
        "representation": representation,
        "wall_s": round(wall, 2),
        "episodes_per_s": round(episodes / wall, 2),
        **{k: summary[k] for k in keep},
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--episodes", type=int, default=1400)
    p.add_argument("--dense-episodes", type=int, default=50)
    p.add_argument("--profile-episodes", type=int, default=100)
    p.add_argument("--workers", type=int, default=0, help="0 = one per CPU core")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="bench_dataset_"))
    out.mkdir(parents=True, exist_ok=True)
    print(f"cpu cores: {os.cpu_count()}  load average: {os.getloadavg()[0]:.2f}  output: {out}", flush=True)
    results = {}
    results["keyframe_e2e"] = end_to_end("keyframe", args.episodes, args.workers, out)
    print(json.dumps(results["keyframe_e2e"]), flush=True)
    if args.dense_episodes:
        results["dense_e2e"] = end_to_end("dense", args.dense_episodes, args.workers, out)
        print(json.dumps(results["dense_e2e"]), flush=True)
    results["keyframe_breakdown"] = breakdown("keyframe", args.profile_episodes, out)
    print(json.dumps(results["keyframe_breakdown"]), flush=True)
    if args.dense_episodes:
        results["dense_breakdown"] = breakdown("dense", max(5, args.dense_episodes // 5), out)
        print(json.dumps(results["dense_breakdown"]), flush=True)
    kf = results["keyframe_e2e"]
    print(
        f"\n{args.episodes} keyframe episodes in {kf['wall_s']} s ({kf['episodes_per_s']} episodes/s) "
        f"with {kf['workers']} workers"
        + (f"; target (1400 in < 60 s): {'met' if kf['wall_s'] < 60 else 'NOT met'}" if args.episodes == 1400 else "")
    )
    if args.out is None:
        shutil.rmtree(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
