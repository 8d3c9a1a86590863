"""Where and how a study ran, for its report: the machine, the code's commit, the date and the command line."""

from __future__ import annotations

import os
import platform
import sys
from datetime import UTC, datetime
from pathlib import Path

from lerobot_pnp.report.code_provenance import SOURCE_ROOT, checkout_commit, study_code_changes
from lerobot_pnp.version import __version__


def machine() -> dict:
    """The machine the study ran on (CPU model, cores, Python, OS, library versions) and the code it ran: the
    commit checked out (None outside a git checkout), whether the study's code had uncommitted changes, the
    package version, and the date (UTC) -- what a rerun elsewhere needs to know it runs the same study."""
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
        **code_identity(),
        "date": datetime.now(UTC).strftime("%Y-%m-%d"),
    }


def code_identity(root: Path = SOURCE_ROOT) -> dict:
    """The commit of the checkout at ``root`` and whether the study's code differs from it (None, None when the
    package was not imported from a git checkout), with the package version."""
    commit = checkout_commit(root)
    dirty = None if commit is None else not study_code_changes(root, commit).same
    return {"commit": commit, "uncommitted_changes": dirty, "lerobot_pnp": __version__}


def command() -> str:
    args = " ".join(sys.argv[1:]) if sys.argv and Path(sys.argv[0]).name.startswith("lerobot-pnp") else ""
    return f"lerobot-pnp {args}".strip() if args else "lerobot_pnp.report.run.run_study (library call)"
