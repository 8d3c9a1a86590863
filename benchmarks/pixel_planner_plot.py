"""The camera planner's success against training time, one line per run of ``pixel_planner.py``: data, encoder input
and steps apart, with each checkpoint's 95 % Wilson interval (the curve of docs/results/pixel_planner.md).

It reads only the committed result files, so the figure changes only when a record does:

    .venv/bin/python benchmarks/pixel_planner_plot.py --out docs/results/pixel_planner_curve.png
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import NamedTuple

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"
BUDGET_MIN = 30  # the training budget on 2 cores, minutes


class Run(NamedTuple):
    """One run of ``pixel_planner.py`` on the page: its record (under docs/results/) and what it trained."""

    record: str
    demos: int
    encoder: str  # the resolution the encoder reads
    steps: int
    note: str = ""  # how it ran, where it differs from one torch thread

    @property
    def label(self) -> str:
        return f"{self.demos}, {self.encoder}, {self.steps} steps{self.note}"


# each record's checkpoints as pixel_planner.py writes them ("nominal") or the longer-schedule form ("curve")
RUNS = (
    Run("pixel_planner.json", 300, "64x64", 800),
    Run("pixel_baselines/longer_schedule.json", 300, "64x64", 3200),
    Run("pixel_planner_1200.json", 1200, "64x64", 2000),
    Run("pixel_planner_1200_32px.json", 1200, "32x32 (pooled)", 2000),
    Run("pixel_planner_1200_32px_long.json", 1200, "32x32 (pooled)", 6000),
    Run("pixel_planner_3600_32px.json", 3600, "32x32 (pooled)", 6000),
    Run("pixel_planner_7200_32px.json", 7200, "32x32 (pooled)", 9000, " (2 threads)"),
    Run("pixel_planner_7200_strength.json", 7200, "32x32 (pooled) + strength", 9000, " (2 threads, seed 1002)"),
    Run(
        "pixel_planner_7200_pose.json",
        7200,
        "32x32 (pooled) + strength, pose loss 1.0",
        9000,
        " (2 threads, seed 1002)",
    ),
)


def checkpoints(record: dict) -> list[dict]:
    """Each checkpoint's training time, success and interval, in training order."""
    return sorted(record.get("nominal") or record["curve"], key=lambda r: r["train_time_s"])


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=RESULTS / "pixel_planner_curve.png")
    args = parser.parse_args()
    fig, (ax, by_data) = plt.subplots(1, 2, figsize=(12, 5.4), dpi=110, gridspec_kw={"width_ratios": [3, 2]})
    for i, run in enumerate(RUNS):
        rows = checkpoints(json.loads((RESULTS / run.record).read_text()))
        t = [r["train_time_s"] / 60 for r in rows]
        y = [r["success_pct"] for r in rows]
        low = [r["success_pct"] - r["wilson95_pct"][0] for r in rows]
        high = [r["wilson95_pct"][1] - r["success_pct"] for r in rows]
        ax.errorbar(t, y, yerr=[low, high], marker="o", capsize=3, label=f"{run.label.replace(', ', ' demos, ', 1)}")
        within = [k for k, minutes in enumerate(t) if minutes <= BUDGET_MIN]
        if within:  # the run's last checkpoint inside the budget, against its data
            k = within[-1]
            by_data.errorbar([run.demos], [y[k]], yerr=[[low[k]], [high[k]]], marker="o", capsize=3, color=f"C{i}")
    ax.axvline(BUDGET_MIN, color="grey", linestyle=":", linewidth=1)
    ax.text(BUDGET_MIN + 0.5, 88, "30 min budget", color="grey", fontsize=8)
    ax.set_xlabel("training time (minutes; one torch thread, or two where the legend says so)")
    ax.set_ylabel("nominal success, % (100 or 200 episodes, 95 % Wilson)")
    ax.set_title("Camera planner on full: success against training time", fontsize=10)
    handles, labels = ax.get_legend_handles_labels()
    by_data.set_xscale("log")
    by_data.minorticks_off()
    by_data.set_xlim(200, 10000)
    demos = sorted({run.demos for run in RUNS})
    by_data.set_xticks(demos, [str(n) for n in demos])
    by_data.set_xlabel("demonstrations")
    by_data.set_title("... and against data: each run's last checkpoint within 30 min", fontsize=10)
    for a in (ax, by_data):
        a.axhline(95, color="grey", linestyle="--", linewidth=1)
        a.set_ylim(0, 100)
    ax.text(36, 96.5, "95 % target", color="grey", fontsize=8)
    fig.tight_layout(rect=(0, 0.16, 1, 1))  # the legend below both panels, clear of every line
    fig.legend(handles, labels, fontsize=7.5, loc="lower center", ncol=3, frameon=False)
    fig.savefig(args.out)
    print(args.out)


if __name__ == "__main__":
    main()
