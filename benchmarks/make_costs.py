"""What the README's make targets cost from a fresh clone: ``make install``, ``make test`` and ``make demo``, one after
the other in a new clone of this checkout's commit, on this machine.

Each target is measured as ``benchmarks/command_costs.py`` measures a command (its wall clock; the CPU time of it
and every process it waited for; the peak of its process tree's summed resident sets, sampled; what it added to
the clone, in MB): ``make install`` creates the venv and installs the lock into it, ``make test`` runs ruff, the
import layers, the whole test suite on both cores and the strict documentation build (its pytest summary line is
kept: how many tests ran, how many were skipped), ``make demo`` the end-to-end job from empty output folders. The
clone has no venv, no dataset and no byte-code caches of its own; the package manager's download cache (uv's)
is the machine's, as it is for anyone who has installed once. The test suite's SLURM tests run where SLURM
answers (``benchmarks/slurm_local_cluster.sh start``) and skip themselves otherwise: the record says which.

    OMP_NUM_THREADS=1 MUJOCO_GL=egl HF_HUB_OFFLINE=1 python benchmarks/make_costs.py \\
        [--out docs/results/make_costs.json] [--targets install test demo] [--keep FOLDER]

The commit measured is this checkout's ``HEAD``; uncommitted changes are not in the clone, so the script refuses
to run with any (they would not be what the record names). ``scripts/docs_tables.py`` renders ``docs/costs.md``'s
make-target table and the README's cost line from the record.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from command_costs import ROOT, run_command, write_record

TARGETS = ("install", "test", "demo")
_SUMMARY = re.compile(r"^=*\s*(\d+ passed.*?) in [\d.]+s", re.M)


def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()


def pytest_summary(log: str) -> str | None:
    """The last pytest summary line of a log ("1025 passed, 2 warnings"), without its time."""
    found = _SUMMARY.findall(log)
    return found[-1] if found else None


def measure(targets: list[str], clone: Path, logs: Path) -> list[dict]:
    rows = []
    for target in targets:
        log = logs / f"make_{target}.log"
        row = run_command(["make", target], clone, log, executable="make")
        if target == "test":
            row["tests"] = pytest_summary(log.read_text(errors="replace"))
        rows.append(row)
        extra = f"  {row['tests']}" if row.get("tests") else ""
        print(f"{row['wall_s']:8.1f} s {row['cpu_s']:8.1f} s CPU {row['disk_mb']:8.1f} MB  make {target}{extra}")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "make_costs.json")
    parser.add_argument("--targets", nargs="+", choices=TARGETS, default=list(TARGETS))
    parser.add_argument("--keep", type=Path, default=None, help="clone into this new folder and keep it")
    args = parser.parse_args(argv)
    if _git("status", "--porcelain", "--untracked-files=no"):
        raise SystemExit("the checkout has uncommitted changes: commit them first (the clone measures HEAD)")
    commit = _git("rev-parse", "HEAD")
    with tempfile.TemporaryDirectory(prefix="make_costs_") as tmp:
        clone = args.keep or Path(tmp) / "clone"
        if clone.exists():
            raise SystemExit(f"{clone} exists: --keep takes a new folder")
        subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
        subprocess.run(["git", "-C", str(clone), "checkout", "-q", commit], check=True)
        rows = measure(args.targets, clone, Path(tmp))
        sinfo = subprocess.run(["sinfo", "-h"], capture_output=True, text=True) if shutil.which("sinfo") else None
    sys.path.insert(0, str(ROOT))
    from lerobot_pnp.report.provenance import machine  # after the targets: this process stays small meanwhile

    env = {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "MUJOCO_GL", "HF_HUB_OFFLINE")}
    record = {
        "machine": {**machine(), "commit": commit, "uncommitted_changes": False},
        "environment": env,
        "slurm": bool(sinfo and sinfo.returncode == 0 and sinfo.stdout.strip()),
        "targets": {f"make {row['command'].split()[-1]}": row for row in rows},
    }
    write_record(record, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
