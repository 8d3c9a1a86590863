"""The table of ``benchmarks/image_policies.sh``: success with 95 % Wilson intervals from each ``eval_info.json``.

Usage: ``python benchmarks/image_policies_table.py OUT run [run ...]`` (runs are folders ``OUT/eval_<run>``).
Every run was evaluated on the same seeded episodes, so the exact McNemar p-value against the first run is
given too (``lerobot_pnp.evaluation.stats``, the study's own statistics).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from lerobot_pnp.evaluation.stats import Rate, sign_test_p


def successes(eval_dir: Path) -> list[bool]:
    """Per-episode success, in seed order, from stock ``lerobot-eval``'s ``eval_info.json``."""
    info = json.loads((eval_dir / "eval_info.json").read_text())
    return [bool(s) for task in info["per_task"] for s in task["metrics"]["successes"]]


def seconds(out: Path) -> dict[str, int]:
    times = out / "times.txt"
    lines = times.read_text().split("\n") if times.is_file() else []
    return {name: int(t) for name, t in (line.split() for line in lines if line.strip())}


def table(out: Path, runs: list[str]) -> str:
    took = seconds(out)
    first = successes(out / f"eval_{runs[0]}")
    rows = ["| policy | success [95 % Wilson] | episodes | vs first (McNemar p) | train wall s | eval wall s |",
            "|---|---|---|---|---|---|"]  # fmt: skip
    for run in runs:
        got = successes(out / f"eval_{run}")
        wins = sum(a and not b for a, b in zip(got, first, strict=True))
        losses = sum(b and not a for a, b in zip(got, first, strict=True))
        p = "-" if run == runs[0] else f"{sign_test_p(wins, losses):.2g}"
        train_s = took.get(f"train_{run}", "?")
        rows.append(f"| {run} | {Rate.of(got)} | {len(got)} | {p} | {train_s} | {took.get(f'eval_{run}', '?')} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(table(Path(sys.argv[1]), sys.argv[2:]))
