"""The study's local path beside a baseline revision, side by side: the same tiny study, wall clock per run.

`lerobot-pnp report` gained ``--executor slurm``; its default (``local``) must cost what it cost before. This runs
the tiny study of ``tests/test_report_slurm.py`` (10 demonstrations, one epoch, the lookup table and the
clocked LSTM on two nominal episodes) from scratch in a fresh process, in turn from a revision and from a
baseline revision, both exported with ``git archive`` (new then old, old then new, ...), each into a new output
folder, and prints each side's runs and median: the process's wall clock, and the study's own (``summary.json``
``run/wall_clock``: the stages, imports left out). With ``--slurm PARTITION`` it also runs the study once as cluster jobs
(``--executor slurm``, from the installed package, which its jobs import) and prints its wall clock and the jobs
it submitted.

    OMP_NUM_THREADS=1 MUJOCO_GL=egl HF_HUB_OFFLINE=1 python benchmarks/bench_study_executor.py \\
        --baseline de34a60 [--revision HEAD] [--rounds 3] [--workers 1] [--slurm cpu]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STUDY = ["--preset", "quick", "--num_episodes", "10", "--epochs", "1", "--train_seeds", "[1000]",
         "--methods", "[lookup_table,clocked_lstm]", "--cli_check_episodes", "0",
         "--suites", "[{name: nominal, n_episodes: 2}]"]  # fmt: skip


def export(revision: str, into: Path) -> Path:
    """The package of ``revision`` in ``into`` (``git archive``), laid out as installed (the scene in
    ``lerobot_pnp/assets``): imported ahead of the installed one."""
    archive = into / f"{revision}.tar"
    subprocess.run(["git", "-C", str(ROOT), "archive", "-o", str(archive), revision, "lerobot_pnp", "envs"], check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(into / revision, filter="data")
    (into / revision / "envs").rename(into / revision / "lerobot_pnp" / "assets")
    return into / revision


# the package imported from the folder given first, not from the editable install's finder
LAUNCH = """import sys
sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in str(f).lower()]
sys.path.insert(0, sys.argv.pop(1))
import lerobot_pnp
assert lerobot_pnp.__file__.startswith(sys.path[0]), lerobot_pnp.__file__
from lerobot_pnp.cli import main
sys.exit(main(sys.argv[1:]))
"""


def run(source: Path, out: Path, *flags: str) -> float:
    """Wall seconds of one study from scratch, its package imported from ``source``."""
    cmd = [sys.executable, "-c", LAUNCH, str(source), "report", "--output_dir", str(out), *STUDY, *flags]
    t = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--baseline", required=True, help="the git revision to compare with (e.g. the commit before)")
    p.add_argument("--revision", default="HEAD", help="the git revision measured (default: HEAD)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--slurm", metavar="PARTITION", help="also run the study once as cluster jobs on this partition")
    args = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_study_") as tmp:
        tmp = Path(tmp)
        sides = {args.revision: export(args.revision, tmp), args.baseline: export(args.baseline, tmp)}
        times: dict[str, list[float]] = {name: [] for name in sides}
        study: dict[str, list[float]] = {name: [] for name in sides}  # the study's own wall, imports left out
        for r in range(args.rounds):
            for name, source in list(sides.items())[:: 1 if r % 2 == 0 else -1]:  # each side first in turn
                out = tmp / f"out_{name}_{r}"
                times[name].append(run(source, out, "--workers", str(args.workers)))
                study[name].append(json.loads((out / "summary.json").read_text())["timings_s"]["run/wall_clock"])
                print(f"round {r + 1}: {name}: {times[name][-1]:.1f} s (study {study[name][-1]:.1f} s)", flush=True)
        for name, t in times.items():
            print(f"{name}: median {statistics.median(t):.1f} s of {', '.join(f'{x:.1f}' for x in t)}; the study "
                  f"itself: median {statistics.median(study[name]):.1f} s")  # fmt: skip
        if args.slurm:
            out = tmp / "slurm"
            flags = ["--executor", "slurm", "--slurm.partition", args.slurm, "--slurm.mem_per_cpu_gb", "1"]
            wall = run(ROOT, out, *flags)  # the cluster jobs' Python imports the installed package
            jobs = json.loads((out / "slurm" / "jobs.json").read_text())["job_ids"]
            print(f"slurm: {wall:.1f} s, the dataset's job then {len(jobs)} cluster jobs ({', '.join(jobs)})")


if __name__ == "__main__":
    main()
