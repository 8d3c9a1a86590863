"""Dataset generation throughput, side by side with a reference tree, and where the time goes.

    .venv/bin/python benchmarks/bench_dataset.py [--num_episodes 1400] [--workers 2] [--old-tree /tmp/old]
                                                 [--dense-episodes 0] [--profile-episodes 100] [--out DIR]

1. The paper's dataset (1400 keyframe episodes) end to end through the real CLI (``lerobot-pnp generate``:
   datatrove tasks, merge, verification), wall time measured from outside. With ``--old-tree`` (a checkout
   of an older commit, e.g. ``git worktree add /tmp/old 96a8930``: the hand-written process pool) the same
   command runs from that tree right after, with the same seed, and the two content hashes must be equal.
   Target: new wall time <= old wall time (on the same, equally loaded, machine); the load average before
   each run is printed because the machine may be shared.
2. Dense episodes (20 fps, state only) the same way (new tree only).
3. A single-process breakdown of one shard: the share of wall time in MuJoCo physics (mj_step), IK
   (ArmIK.solve/refine/forward, incl. the straight-line path correction), the rest of the expert/env Python,
   and LeRobot's writer (add_frame + save_episode + finalize).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

HERE = Path(__file__).resolve().parents[1]
PNP = str(Path(sys.executable).parent / "lerobot-pnp")


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


def cli_run(
    tree: Path, root: Path, episodes: int, workers: int, dense: bool = False, preset: str | None = None
) -> dict:
    """``lerobot-pnp generate`` from ``tree`` (PYTHONPATH), timed from outside; returns its summary + hash."""
    args = [PNP, "generate", "--repo_id=bench/kf", f"--root={root}", f"--num_episodes={episodes}", "--seed=0"]
    args += ["--progress=false"] + ([f"--workers={workers}"] if workers else [])
    if dense:
        new_api = (tree / "lerobot_pnp" / "dataset" / "__init__.py").exists()
        args += ["--env.control_mode=dense", "--env.fps=20"] if new_api else ["--representation=dense", "--fps=20"]
    if preset:
        args.append(f"--env.preset={preset}")
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1"}
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    res = subprocess.run(args, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if res.returncode != 0:
        raise SystemExit(f"{tree}: generate failed:\n{res.stderr[-3000:]}")
    summary = json.loads(res.stdout)
    code = f"from lerobot_pnp.dataset import data_hash; print(data_hash({str(root)!r}))"
    digest = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env).stdout.strip()
    keep = ("episodes", "shards", "workers", "generate_wall_s", "merge_wall_s", "simulate_cpu_s", "write_cpu_s")
    return {"tree": str(tree), "load_before": round(load, 2), "wall_s": round(wall, 2),
            "episodes_per_s": round(episodes / wall, 2), **{k: summary.get(k) for k in keep}, "hash": digest}  # fmt: skip


def breakdown(control_mode: str, episodes: int, out: Path) -> dict:
    """Run one shard in this process with timers around physics and IK."""
    import mujoco

    from lerobot_pnp.dataset.shards import GenerateShard, quiet_and_single_threaded, read_shard_record
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.sim.ik import ArmIK

    quiet_and_single_threaded()
    physics, ik = _Timer(), _Timer()
    saved = (mujoco.mj_step, ArmIK.solve, ArmIK.refine, ArmIK.forward)
    mujoco.mj_step = physics.wrap(mujoco.mj_step)
    ArmIK.solve, ArmIK.refine, ArmIK.forward = (ik.wrap(ArmIK.solve), ik.wrap(ArmIK.refine), ik.wrap(ArmIK.forward))
    work = out / f"breakdown_{control_mode}"
    env = BaxterPnPEnvConfig(control_mode=control_mode).to_dict()
    step = GenerateShard(str(work), "bench/breakdown", env, seed=0, num_episodes=episodes, max_retries=10)
    try:
        t0 = time.perf_counter()
        step.write(0, 1)
        wall = time.perf_counter() - t0
    finally:
        mujoco.mj_step, ArmIK.solve, ArmIK.refine, ArmIK.forward = saved
    rec = read_shard_record(work, 0)
    other_sim = rec["sim_s"] - physics.total - ik.total
    return {
        "control_mode": control_mode,
        "episodes": episodes,
        "wall_s": round(wall, 2),
        "ms_per_episode": round(1000 * wall / episodes, 1),
        "share_physics": round(physics.total / wall, 3),
        "share_ik": round(ik.total / wall, 3),
        "share_other_sim": round(other_sim / wall, 3),
        "share_writing": round(rec["write_s"] / wall, 3),
        "write_ms_per_episode": round(1000 * rec["write_s"] / episodes, 1),
    }


def _print_ratio(episodes: int, a: tuple[str, dict], b: tuple[str, dict], note: str) -> None:
    """One line comparing two generation runs measured side by side (wall time ratio, load before each)."""
    (name_a, ra), (name_b, rb) = a, b
    print(
        f"\n{episodes} keyframe episodes: {name_a} {ra['wall_s']} s vs {name_b} {rb['wall_s']} s "
        f"({name_a}/{name_b} = {ra['wall_s'] / rb['wall_s']:.2f}; load before: {ra['load_before']} / "
        f"{rb['load_before']}); {note}",
        flush=True,
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--num_episodes", type=int, default=1400)
    p.add_argument("--workers", type=int, default=0, help="0 = one per CPU core")
    p.add_argument("--old-tree", type=Path, default=None, help="reference checkout run side by side")
    p.add_argument("--dense-episodes", type=int, default=0)
    p.add_argument("--profile-episodes", type=int, default=0)
    p.add_argument(
        "--full-vs-paper", action="store_true", help="also generate the `full` task's dataset (target <= 2x)"
    )
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="bench_dataset_"))
    out.mkdir(parents=True, exist_ok=True)
    print(f"cpu cores: {os.cpu_count()}  load average: {os.getloadavg()[0]:.2f}  output: {out}", flush=True)
    results = {"new": cli_run(HERE, out / "new", args.num_episodes, args.workers)}
    print(json.dumps(results["new"]), flush=True)
    if args.old_tree:
        results["old"] = cli_run(args.old_tree, out / "old", args.num_episodes, args.workers)
        print(json.dumps(results["old"]), flush=True)
        same = results["new"]["hash"] == results["old"]["hash"]
        _print_ratio(args.num_episodes, ("new", results["new"]), ("old", results["old"]), f"same content hash: {same}")
    if args.full_vs_paper:
        results["full"] = cli_run(HERE, out / "full", args.num_episodes, args.workers, preset="full")
        print(json.dumps(results["full"]), flush=True)
        _print_ratio(args.num_episodes, ("full", results["full"]), ("paper", results["new"]), "target <= 2")
    if args.dense_episodes:
        results["dense"] = cli_run(HERE, out / "dense", args.dense_episodes, args.workers, dense=True)
        print(json.dumps(results["dense"]), flush=True)
    if args.profile_episodes:
        results["keyframe_breakdown"] = breakdown("keyframe", args.profile_episodes, out)
        print(json.dumps(results["keyframe_breakdown"]), flush=True)
    if args.out is None:
        shutil.rmtree(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
