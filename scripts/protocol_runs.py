"""Where the held-out protocol's runs live, for the scripts that read them (``heldout_protocol_eval.py`` writes
them; ``latency_decisions.py`` and ``latency_ensemble.py`` read them).

A run ``RUN`` is the folder ``outputs/RUN``; its ``train_done.json`` names the checkpoint it trained. The task
every protocol suite changes is the one recorded with the protocol's demonstrations in ``outputs/ds_full``.
"""

from __future__ import annotations

import json
from pathlib import Path

OUTPUTS = Path("outputs")
TASK_ROOT = OUTPUTS / "ds_full"  # the demonstrations whose recorded task the suites change


def run_dir(run: str) -> Path:
    return OUTPUTS / run


def checkpoint(run: str) -> Path:
    """The checkpoint run ``RUN`` trained, from ``outputs/RUN/train_done.json``; a clear error if it has none."""
    done = run_dir(run) / "train_done.json"
    if not done.is_file():
        raise SystemExit(f"no trained run {run!r}: {done} is missing (train it with scripts/heldout_protocol_eval.py)")
    return Path(json.loads(done.read_text())["checkpoint"])
