"""What ``lerobot-pnp compare`` costs as the episodes per suite grow: it should grow linearly.

Two runs on the held-out protocol's 18 suites (``--env.task heldout``), written as the two layouts compare reads:
``stock`` as stock ``lerobot-eval`` writes its ``eval_info.json`` (sum and max rewards and successes per episode,
``indent=2``), ``expert`` as ``lerobot-pnp expert`` does (the same plus each episode's seed and failure cause).
Outcomes are random at 80 % and 70 % success, so that the paired tests meet many discordant pairs. For each size
this times one ``run_compare`` (read and check both files, every rate, control-arm difference, paired test and
held-out verdict, render and write compare.md, compare.json and compare.png; the markdown it prints is
discarded) in a fresh process, after its imports and a comparison of 10 episodes per suite, and reports the
time per size, the growth exponent between the two largest sizes (1: linear) and the peak memory of that
process (Linux's VmHWM; the package's imports are most of it at small sizes). Target: 100,000 episodes per
suite under 5 s.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/compare_cost.py [--sizes 12500 25000 50000 100000] \\
        [--workdir outputs/compare_cost] [--out outputs/compare_cost/compare_cost.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import shutil
import subprocess
import sys
from pathlib import Path

from lerobot_pnp.sim.stock_suites import suite_names

TARGET_EPISODES, TARGET_SECONDS = 100_000, 5.0
RATES = {"stock": 0.8, "expert": 0.7}
SEED = 100_000

# argv: the warm-up's two runs, then the measured two runs; prints the seconds of the measured comparison and the
# process's peak memory (MB; VmHWM, which, unlike ru_maxrss, does not carry the parent's peak across the exec).
_CHILD = r"""
import contextlib, io, json, sys, time
from lerobot_pnp.evaluation.compare import CompareConfig, run_compare
for specs, out in ((sys.argv[1:3], sys.argv[5]), (sys.argv[3:5], sys.argv[6])):
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        run_compare(CompareConfig(runs=specs, output_dir=out))
    seconds = time.perf_counter() - start
peak_kb = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM:"))
print(json.dumps({"seconds": seconds, "peak_mb": peak_kb / 1024}))
"""


def eval_info(n: int, rate: float, seeds: bool, rng: random.Random) -> dict:
    """One run's eval_info.json: ``n`` episodes on every suite of the held-out protocol."""
    per_task, per_group = [], {}
    for suite in suite_names("heldout"):
        ok = [rng.random() < rate for _ in range(n)]
        rewards = [float(x) for x in ok]
        metrics = {"sum_rewards": rewards, "max_rewards": rewards, "successes": ok}
        if seeds:
            metrics |= {"seeds": list(range(SEED, SEED + n)), "failure_causes": ["" if x else "dropped" for x in ok]}
        per_task.append({"task_group": suite, "task_id": 0, "metrics": {**metrics, "video_paths": []}})
        per_group[suite] = {"pc_success": 100 * sum(ok) / n, "n_episodes": n, "video_paths": []}
    return {"per_task": per_task, "per_group": per_group, "overall": {"n_episodes": n * len(per_group)}}


def write_runs(n: int, folder: Path) -> list[str]:
    """Both runs at ``n`` episodes per suite under ``folder``: their NAME=PATH arguments."""
    rng = random.Random(n)
    shutil.rmtree(folder, ignore_errors=True)
    specs = []
    for name, rate in RATES.items():
        path = folder / name
        path.mkdir(parents=True)
        (path / "eval_info.json").write_text(json.dumps(eval_info(n, rate, name == "expert", rng), indent=2))
        specs.append(f"{name}={path}")
    return specs


def measure(n: int, workdir: Path) -> dict:
    """Write both runs at ``n`` episodes per suite, then time one comparison of them in a fresh process."""
    warm, specs = write_runs(10, workdir / "warm"), write_runs(n, workdir / f"n{n}")
    outs = [str(workdir / "warm" / "compare"), str(workdir / f"n{n}" / "compare")]
    proc = subprocess.run([sys.executable, "-c", _CHILD, *warm, *specs, *outs], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"compare failed at {n} episodes per suite:\n{proc.stderr}")
    sizes = {name: (workdir / f"n{n}" / name / "eval_info.json").stat().st_size / 1e6 for name in RATES}
    return {"episodes_per_suite": n, **json.loads(proc.stdout.strip().splitlines()[-1]), "file_mb": sizes}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[12_500, 25_000, 50_000, 100_000])
    parser.add_argument("--workdir", type=Path, default=Path("outputs/compare_cost"))
    parser.add_argument("--out", type=Path, default=None, help="also write the results as JSON here")
    args = parser.parse_args()
    sizes = sorted(set(args.sizes))
    print(f"lerobot-pnp compare, 2 runs x {len(suite_names('heldout'))} suites (held-out protocol)")
    rows = []
    for n in sizes:
        row = measure(n, args.workdir)
        rows.append(row)
        files = ", ".join(f"{k} {v:.0f} MB" for k, v in row["file_mb"].items())
        print(f"  {n:>9,} episodes per suite: {row['seconds']:6.2f} s, peak {row['peak_mb']:5.0f} MB   "
              f"(eval_info.json: {files})", flush=True)  # fmt: skip
    growth = None
    if len(rows) >= 2:
        (a, b) = rows[-2:]
        growth = math.log(b["seconds"] / a["seconds"]) / math.log(b["episodes_per_suite"] / a["episodes_per_suite"])
        print(f"  growth exponent between the two largest sizes: {growth:.2f} (1: linear)")
    at_target = next((r["seconds"] for r in rows if r["episodes_per_suite"] == TARGET_EPISODES), None)
    met = at_target is not None and at_target < TARGET_SECONDS
    print(f"  target: {TARGET_EPISODES:,} episodes per suite under {TARGET_SECONDS} s: "
          + ("not measured" if at_target is None else "met" if met else "missed"))  # fmt: skip
    if args.out is not None:
        result = {"rows": rows, "growth_exponent": growth, "python": sys.version.split()[0],
                  "cpus": os.cpu_count(), "target": {"episodes_per_suite": TARGET_EPISODES, "seconds": TARGET_SECONDS},
                  "target_met": met}  # fmt: skip
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(result, indent=2) + "\n")
        print(f"  written to {args.out}")
    return 0 if met or at_target is None else 1


if __name__ == "__main__":
    sys.exit(main())
