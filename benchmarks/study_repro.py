"""Whether a rerun of the study reproduces another: two ``summary.json`` compared cell by cell and verdict by
verdict (the rules: ``lerobot_pnp.report.repro``).

    python benchmarks/study_repro.py docs/results/study/heldout/summary.json outputs/heldout/summary.json \\
        [--out table.md] [--all-cells]

Prints a one-line summary and a markdown table (also written to ``--out``): the suite x method cells whose
success differs beyond the intervals of the two runs, and every held-out verdict of both runs by today's rule.
A method that only one run's config evaluates (a study that dropped or added a method) is a difference of config,
not of reproduction: its cells and verdicts are left out and named above the table.
Exit status 1 when a headline verdict (the recovering planner's, on a held-out axis) changes, 2 for a bad
argument, 0 otherwise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from lerobot_pnp.errors import PnPError
from lerobot_pnp.evaluation.verdicts import difference_interval
from lerobot_pnp.outputs import OutputFolder
from lerobot_pnp.report.repro import compare, load_summary, render


def describe(path: Path, summary: dict) -> str:
    """The summary's file and where it was made (CPU, cores, commit, date as recorded)."""
    m = summary.get("machine", {})
    commit = m.get("commit") or "commit not recorded"
    return (
        f"`{path}` ({m.get('cpu', '?')}, {m.get('cores_available', '?')} cores; {commit}; {m.get('date', 'no date')})"
    )


def by_episodes(result) -> str:
    """The cells whose difference the episodes alone call (Newcombe's interval excludes 0), each beside its interval
    with the training seeds counted: what a comparison that ignores the seeds would flag."""
    both = [c for c in result.cells if c.a is not None and c.b is not None]
    rows = []
    for c in both:
        lo, hi = difference_interval(c.a, c.b)
        if lo > 0 or hi < 0:
            slo, shi = c.interval
            rows.append(
                f"| {c.suite} | {c.method} | {100 * c.a.rate:.1f} % | {100 * c.b.rate:.1f} % | "
                f"{100 * (c.b.rate - c.a.rate):+.1f} | [{100 * lo:+.1f}, {100 * hi:+.1f}] | [{100 * slo:+.1f}, {100 * shi:+.1f}] |"
            )
    same = sum(c.a == c.b for c in both)
    equal = f"{same} of {len(both)} cells have the same successes of the same episode count in both runs. "
    head = [
        equal + f"{len(rows)} cells differ by their episodes alone (the seeds not counted):",
        "",
        "| suite | method | A | B | B - A | episodes only [95 %] | seeds counted [95 %] |",
        "|---|---|---|---|---|---|---|",
    ]
    return "\n".join(head + rows) + "\n" if rows else equal + "No cell differs by its episodes alone either.\n"


def shared_methods(a: dict, b: dict) -> tuple[dict, dict, list[str]]:
    """Both summaries cut to the methods both evaluated, and a line per run naming the methods only it has."""
    methods = [{m for row in s["success"].values() for m in row} for s in (a, b)]
    both = methods[0] & methods[1]

    def cut(summary: dict) -> dict:
        success = {suite: {m: c for m, c in row.items() if m in both} for suite, row in summary["success"].items()}
        axes = [e for e in summary.get("held_out_axes", []) if e["method"] in both]
        return {**summary, "success": success, "held_out_axes": axes}

    only = [f"{run} only, left out: {', '.join(sorted(m - both))}" for run, m in zip("AB", methods) if m - both]
    return cut(a), cut(b), only


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", type=Path, help="the reference summary.json")
    parser.add_argument("b", type=Path, help="the rerun's summary.json")
    parser.add_argument("--out", type=Path, help="also write the markdown here (a new file or one this wrote)")
    parser.add_argument("--all-cells", action="store_true", help="list every cell, not only those that differ")
    parser.add_argument(
        "--by-episodes",
        action="store_true",
        help="also list the cells whose episodes alone (Newcombe's interval, the seeds not counted) differ",
    )
    args = parser.parse_args(argv)
    try:
        a, b = load_summary(args.a), load_summary(args.b)
        a, b, only = shared_methods(a, b)
        result = compare(a, b)
        text = render(result, describe(args.a, a), describe(args.b, b), args.all_cells)
        if args.by_episodes:
            text = text.rstrip() + "\n\n" + by_episodes(result)
        if only:
            head, _, rest = text.partition("\n")
            text = head + "\n\n" + "".join(f"Methods in {line}.  \n" for line in only).rstrip() + "\n" + rest
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
