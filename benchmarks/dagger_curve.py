"""The learning curve of ``lerobot-pnp dagger`` runs: success per round with 95 % Wilson intervals, the labels
each round added, the rollouts' label statistics and the wall time (docs/guides/dagger-dart.md).

``python benchmarks/dagger_curve.py NAME=OUTPUT_DIR ... [--round0 OUTPUT_DIR] [--json FILE]``: one column
block per run; ``--round0`` names the run whose round-0 time is reported when the runs reused a copied round 0.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from dagger_labels import round_stats

from lerobot_pnp.evaluation.stats import Rate


def run_curve(out: Path, round0: Path | None) -> dict:
    """Per round: success per eval suite, labels (frames) added, policy successes in the rollouts, wall time."""
    summary = json.loads((out / "summary.json").read_text())
    times = summary["timings_s"]
    if round0 is not None:
        times = {**times, **json.loads((round0 / "summary.json").read_text())["timings_s"]}
    rounds = []
    for rdir in sorted(d for d in out.glob("round_*") if (d / "eval.json").is_file()):
        rnd = int(rdir.name[6:])
        evals = json.loads((rdir / "eval.json").read_text())
        parts = [times.get(f"round{rnd}_data_s"), times.get(f"round{rnd}_train_s")]  # missing: a run in progress
        wall = None if None in parts else round(sum(parts) + (times.get("demos_s", 0) if rnd == 0 else 0), 1)
        row = {"round": rnd, "success": {}, "wall_s": wall}
        for suite, res in evals.items():
            r = Rate(res["successes"], res["n"])
            row["success"][suite] = {"successes": res["successes"], "n": res["n"], "wilson95": r.interval}
        if rnd > 0:
            rec = summary["rollouts"].get(str(rnd)) or json.loads((rdir / "rollouts.json").read_text())
            keys = ("beta", "dart", "frames", "policy_successes", "executed_labels", "disagree")
            row |= {k: rec.get(k) for k in keys}
            row["labels"] = round_stats(out, rnd, json.loads((rdir / "rollouts.json").read_text())["parts"]["suites"])
        rounds.append(row)
    return {"output_dir": str(out), "rounds": rounds}


def dart_cell(dart: dict | None) -> str:
    """DART's noise of a round's rollouts, as the beta cell's suffix (nothing when off)."""
    if not dart:
        return ""
    flip = f", flip {dart['gripper_flip']:g}" if dart["gripper_flip"] else ""
    return f" + DART (sigma {dart['sigma']:g} rad{flip})"


def table(name: str, curve: dict) -> str:
    suites = list(curve["rounds"][0]["success"])
    head = f"| {name}: round | beta | labels added (frames) | wall s | " + " | ".join(f"`{s}`" for s in suites)
    lines = [head + " |", "|---" * (len(suites) + 4) + "|"]
    total = 0
    for row in curve["rounds"]:
        total += row.get("frames") or 0
        cells = [str(Rate(v["successes"], v["n"])) for v in row["success"].values()]
        beta = "-" if row["round"] == 0 else f"{row['beta']:g}" + dart_cell(row.get("dart"))
        added = "demos" if row["round"] == 0 else f"{row['frames']} (total {total})"
        lines.append(
            f"| {row['round']} | {beta} | {added} | {row['wall_s'] if row['wall_s'] is not None else '-'} | "
            + " | ".join(cells)
            + " |"
        )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="NAME=OUTPUT_DIR")
    ap.add_argument("--round0", type=Path, action="append", default=[], help="per run, in order (optional)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    curves = {}
    for i, spec in enumerate(args.runs):
        name, out = spec.split("=", 1)
        curves[name] = run_curve(Path(out), args.round0[i] if i < len(args.round0) else None)
        print(table(name, curves[name]) + "\n")
    if args.json:
        args.json.write_text(json.dumps(curves, indent=1) + "\n")


if __name__ == "__main__":
    main()
