"""The study's evaluations, this tree against an older checkout, side by side: same records, less time?

Each case re-runs one stored evaluation of a study folder (a method's checkpoint of one training seed on one
suite, its first ``--n_episodes`` episodes from the study's eval seed, the study's batch of 50 envs) with
stock ``eval_policy``, the same call the study makes (``closed_loop``); the expert runs its own loop.
Every case runs in a fresh process, alternating trees (new, old, new, old, ...), so drift on a shared machine
hits both. It prints, per case and in total, the wall time of each tree and their ratio, and checks that both
trees reproduce the stored records episode for episode (a speed-up that changed an outcome would make every
cached evaluation a lie about the code that reads it). Target: new / old <= 0.9 with identical records.

    OMP_NUM_THREADS=1 MUJOCO_GL=egl python benchmarks/bench_eval_env.py --old-tree /tmp/old \\
        [--study outputs/heldout --study outputs/report_full] [--n_episodes 50] [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

CASES = {  # study folder name -> (method, training seed, suite): keyframe planners, ACT in dense mode, the expert
    "heldout": [
        ("recovering", "1000", "heldout_all_at_once"),
        ("recovering", "1001", "heldout_latency_jitter"),
        ("recovering", "1002", "heldout_far_drop"),
        ("act", "1000", "train_drop"),
        ("expert", "-", "heldout_double_displace"),
    ],
    "report_full": [
        ("recovering", "1000", "nudge_0.05"),
        ("clocked_lstm", "1001", "obs_noise_0.01"),
        ("act", "1002", "nominal"),
    ],
}

_CHILD = r"""
import glob, json, sys, time
from pathlib import Path
import torch
torch.set_num_threads(1)
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.evaluation.checkpoints import load_policy
from lerobot_pnp.evaluation.closed_loop import eval_expert, eval_lerobot_policy
from lerobot_pnp.sim.suites import get_suites
from lerobot_pnp.integration.recorded_task import read_recorded
from lerobot_pnp.report import act_baseline

root, method, seed, suite, n = Path(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5])
cfg = json.loads((root / "study_config.json").read_text())
start = int(cfg.get("eval_seed", 100000))
base = BaxterPnPEnvConfig.from_dict(read_recorded(root / "dataset") or {})
env_cfg = get_suites([suite])[0].env_configs(base)[0]
if method == "expert":
    t = time.perf_counter()
    records = eval_expert(env_cfg, n, start)
else:
    ckpt = sorted(glob.glob(str(root / "train" / method / f"seed{seed}" / "checkpoints" / "*" / "pretrained_model")))[-1]
    loaded = load_policy(ckpt)
    if method == "act":
        env_cfg = act_baseline.dense_env(env_cfg, root / "dataset_dense")
    t = time.perf_counter()
    records = eval_lerobot_policy(loaded.policy, loaded.preprocessor, loaded.postprocessor, env_cfg, n, start, 50)
wall = time.perf_counter() - t
import lerobot_pnp
print(json.dumps({"wall_s": wall, "episodes": [vars(r) for r in records], "code": lerobot_pnp.__file__}))
"""


def run_case(tree: Path, study: Path, case: tuple[str, str, str], n: int) -> dict:
    """One evaluation in a fresh process importing ``lerobot_pnp`` from ``tree``; its time excludes start-up."""
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1", "MUJOCO_GL": "egl"}
    # run in the tree: ``python -c`` puts the working directory first on sys.path, before PYTHONPATH
    args = [sys.executable, "-c", _CHILD, str(study.resolve()), *case, str(n)]
    res = subprocess.run(args, capture_output=True, text=True, env=env, cwd=tree)
    if res.returncode != 0:
        sys.exit(f"{tree}: {case} failed:\n{res.stderr[-2000:]}")
    out = json.loads(res.stdout.strip().splitlines()[-1])
    if not out["code"].startswith(str(tree.resolve())):
        sys.exit(f"the run meant for {tree} imported lerobot_pnp from {out['code']}")
    return out


def same_records(stored: list[dict], got: list[dict]) -> bool:
    return len(stored) == len(got) and all(
        all(abs(v - b[k]) <= 1e-12 if isinstance(v, float) else v == b[k] for k, v in a.items())
        for a, b in zip(stored, got, strict=True)
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--old-tree", type=Path, required=True, help="a checkout of the reference commit")
    p.add_argument("--study", type=Path, action="append", help="study folders (default: outputs/heldout, report_full)")
    p.add_argument("--n_episodes", type=int, default=50)
    p.add_argument("--repeats", type=int, default=2, help="runs of every case per tree")
    p.add_argument("--out", type=Path, default=None, help="write the numbers here as JSON")
    args = p.parse_args()
    new_tree = Path(__file__).resolve().parents[1]
    studies = args.study or [Path("outputs/heldout"), Path("outputs/report_full")]
    rows, total = [], {"new": 0.0, "old": 0.0}
    for study in studies:
        for case in CASES[study.name if study.name in CASES else "heldout"]:
            method, seed, suite = case
            record = study / "evals" / method / f"seed{seed}" / f"{suite}.json"
            stored = json.loads(record.read_text())["episodes"][: args.n_episodes]
            walls: dict[str, list[float]] = {"new": [], "old": []}
            same = True
            for _ in range(args.repeats):
                for name, tree in (("new", new_tree), ("old", args.old_tree)):
                    out = run_case(tree, study, case, args.n_episodes)
                    walls[name].append(out["wall_s"])
                    same &= same_records(stored, out["episodes"])
            best = {k: min(v) for k, v in walls.items()}
            total["new"] += best["new"]
            total["old"] += best["old"]
            rows.append({"study": str(study), "case": case, "wall_s": walls, "same_records": same})
            print(
                f"{study.name:12s} {method:13s} {seed:5s} {suite:24s} new {best['new']:6.1f} s  old {best['old']:6.1f} s"
                f"  new/old {best['new'] / best['old']:.2f}  records {'identical' if same else 'DIFFER'}",
                flush=True,
            )
    ratio = total["new"] / total["old"]
    ok = ratio <= 0.9 and all(r["same_records"] for r in rows)
    print(
        f"total (best of {args.repeats} per case): new {total['new']:.1f} s, old {total['old']:.1f} s, "
        f"new/old {ratio:.2f} (target <= 0.9 with identical records: {'PASS' if ok else 'FAIL'})"
    )
    if args.out:
        args.out.write_text(json.dumps({"rows": rows, "total": total, "ratio": ratio, "pass": ok}, indent=1))


if __name__ == "__main__":
    main()
