"""Where and how a study ran, for its report: the machine and the command line."""

from __future__ import annotations

import os
import platform
import sys
from pathlib import Path


def machine() -> dict:
    """The machine the study ran on (for the report)."""
    import importlib.metadata as md

    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = {}
    for pkg in ("lerobot", "torch", "mujoco", "gymnasium", "numpy"):
        try:
            versions[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            versions[pkg] = "?"
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu": cpu,
        "cores_available": cores,
        "python": platform.python_version(),
        "os": platform.platform(),
        **versions,
    }


def command() -> str:
    args = " ".join(sys.argv[1:]) if sys.argv and Path(sys.argv[0]).name.startswith("lerobot-pnp") else ""
    return f"lerobot-pnp {args}".strip() if args else "lerobot_pnp.report.run.run_study (library call)"
