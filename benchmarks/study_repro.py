"""Whether a rerun of the study reproduces another: two ``summary.json`` compared cell by cell and verdict by
verdict (the rules: ``lerobot_pnp.report.repro``).

    python benchmarks/study_repro.py docs/results/study/heldout/summary.json outputs/heldout/summary.json \\
        [--out table.md] [--all-cells]

Prints a one-line summary and a markdown table (also written to ``--out``): the suite x method cells whose
success differs beyond the intervals of the two runs, and every held-out verdict of both runs by today's rule.
Exit status 1 when a headline verdict (the recovering planner's, on a held-out axis) changes, 2 for a bad
argument, 0 otherwise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lerobot_pnp.errors import PnPError
from lerobot_pnp.outputs import OutputFolder
from lerobot_pnp.report.repro import compare, load_summary, render


def describe(path: Path, summary: dict) -> str:
    """The summary's file and where it was made (CPU, cores, commit, date as recorded)."""
    m = summary.get("machine", {})
    commit = m.get("commit") or "commit not recorded"
    return (
        f"`{path}` ({m.get('cpu', '?')}, {m.get('cores_available', '?')} cores; {commit}; {m.get('date', 'no date')})"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", type=Path, help="the reference summary.json")
    parser.add_argument("b", type=Path, help="the rerun's summary.json")
    parser.add_argument("--out", type=Path, help="also write the markdown here (a new file or one this wrote)")
    parser.add_argument("--all-cells", action="store_true", help="list every cell, not only those that differ")
    args = parser.parse_args(argv)
    try:
        a, b = load_summary(args.a), load_summary(args.b)
        result = compare(a, b)
        text = render(result, describe(args.a, a), describe(args.b, b), args.all_cells)
        if args.out:
            with OutputFolder(args.out.parent, "study_repro") as out:
                out.write_text(args.out.name, text)
    except PnPError as e:
        print(f"study_repro: {e}", file=sys.stderr)
        return 2
    print(text, end="")
    return 1 if result.headline_changed else 0


if __name__ == "__main__":
    sys.exit(main())
