"""The study's figures (matplotlib, Agg). Each figure carries the command and config that produced it.

Loss curves (the paper's Fig. 4), success over the workspace, robustness curves with 95 % Wilson intervals,
the data-efficiency curve, success on the recovery suites, the held-out protocol's axes (trained vs held-out
conditions) and failures by FSM phase and cause. Functions take plain data (no simulator).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib
import matplotlib.patches

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.evaluation.stats import Rate

PANELS_PER_ROW = 4  # heat maps and failure panels wrap after this many methods


FOOTER_PT = 6  # the provenance footer's font size


def series_colors(n: int) -> list:
    """``n`` distinct colours, one per method: matplotlib's default cycle (``C0``..``C9``) up to 10, else tab20
    (its dark shades, then its light ones). The default cycle repeats after 10, which gave the study's eleventh
    method the colour of its first."""
    if n <= 10:
        return [f"C{i}" for i in range(n)]
    tab20 = plt.get_cmap("tab20").colors
    order = [*tab20[0::2], *tab20[1::2]]
    if n > len(order):
        raise ValueError(f"at most {len(order)} series can be told apart by colour, got {n}")
    return list(order[:n])


def footer_lines(fig, text: str) -> list[str]:
    """``text`` in lines of the footer's font that fit ``fig``'s width, broken anywhere if need be."""
    per_line = int(fig.get_figwidth() * 72 / (FOOTER_PT * 0.62))  # characters of the footer's font per line
    return textwrap.wrap(text, per_line, break_long_words=True, break_on_hyphens=False) or [""]


def _finish(fig, path: Path, provenance: str) -> Path:
    """Save ``fig`` with its provenance (the command) as a footer, broken into lines that fit the figure's width
    anywhere, since a command's run paths hold no space to wrap at (matplotlib's ``wrap`` breaks at spaces only)."""
    lines = footer_lines(fig, provenance)
    fig.text(0.01, 0.005, "\n".join(lines), fontsize=FOOTER_PT, color="0.35", ha="left", va="bottom")
    footer = (len(lines) * FOOTER_PT * 1.3 + 4) / (fig.get_figheight() * 72)  # its share of the height
    fig.tight_layout(rect=(0, min(footer, 0.3), 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def loss_curves(histories: dict[str, list[dict[str, float]]], path: Path, provenance: str) -> Path:
    """Train and held-out MSE per epoch, one pair of lines per training seed (the paper's Fig. 4)."""
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for i, (label, hist) in enumerate(histories.items()):
        if not hist:
            continue
        ep = [h["epoch"] for h in hist]
        color = f"C{i}"
        ax.plot(ep, [h["train_mse"] for h in hist], color=color, lw=1.2, label=f"train ({label})")
        ax.plot(ep, [h["test_mse"] for h in hist], color=color, lw=1.2, ls="--", label=f"held-out ({label})")
    ax.set_yscale("log")
    ax.set_xlabel("epoch")
    ax.set_ylabel("MSE (normalised actions)")
    ax.set_title("Clocked LSTM: train vs held-out loss (cf. paper Fig. 4)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return _finish(fig, path, provenance)


def success_heatmap(
    panels: dict[str, list], low, high, path: Path, provenance: str, bins: int = 6, title: str = ""
) -> Path:
    """Success rate per cell of the object box, one panel per method (``panels``: name -> EpisodeRecords)."""
    n = len(panels)
    cols = min(n, PANELS_PER_ROW)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols + 1.2, 3.9 * rows), squeeze=False, layout="constrained")
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    xe = np.linspace(low[0], high[0], bins + 1)
    ye = np.linspace(low[1], high[1], bins + 1)
    image = None
    for k, (ax, (name, records)) in enumerate(zip(axes.flat[:n], panels.items(), strict=True)):
        x = np.array([r.object_x for r in records])
        y = np.array([r.object_y for r in records])
        s = np.array([r.success for r in records], dtype=float)
        total, _, _ = np.histogram2d(x, y, bins=(xe, ye))
        good, _, _ = np.histogram2d(x, y, bins=(xe, ye), weights=s)
        rate = np.where(total > 0, good / np.maximum(total, 1), np.nan)
        image = ax.pcolormesh(ye, xe, rate, vmin=0, vmax=1, cmap="RdYlGn")
        for i in range(bins):
            for j in range(bins):
                if total[i, j]:
                    cx, cy = (ye[j] + ye[j + 1]) / 2, (xe[i] + xe[i + 1]) / 2
                    ax.text(cx, cy, f"{int(total[i, j])}", ha="center", va="center", fontsize=6, color="0.2")
        ax.set_title(f"{name}\n{100 * s.mean():.0f}% of {len(s)}", fontsize=9)
        ax.set_xlabel("object y (m)")
        if k % cols == 0:
            ax.set_ylabel("object x (m)")
        ax.invert_xaxis()  # y grows to the robot's left: seen from the robot
        ax.set_aspect("equal")
    fig.colorbar(image, ax=list(axes.flat), label="success rate per cell\n(number = episodes)", shrink=0.85)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.supxlabel(provenance, fontsize=6, color="0.35")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def rate_curves(
    curves: dict[str, list[tuple[float, Rate]]], path: Path, provenance: str, x_label: str, title: str, logx=False
) -> Path:
    """Success rate vs a swept value, one line per method, with 95 % Wilson intervals as bars."""
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    xs = [p[0] for pts in curves.values() for p in pts]
    dodge = 0.012 * (max(xs) - min(xs)) if xs and not logx else 0.0  # overlapping methods stay visible
    colors = series_colors(len(curves))
    for i, (name, points) in enumerate(curves.items()):
        points = sorted(points)
        x = np.array([p[0] for p in points]) + (i - (len(curves) - 1) / 2) * dodge
        if logx:
            x = x * (1.04 ** (i - (len(curves) - 1) / 2))
        r = np.array([100 * p[1].rate for p in points])
        lo = np.array([100 * p[1].interval[0] for p in points])
        hi = np.array([100 * p[1].interval[1] for p in points])
        ax.errorbar(x, r, yerr=[r - lo, hi - r], marker="o", ms=4, capsize=3, color=colors[i], label=name)
    if logx:
        ax.set_xscale("log")
    ax.set_ylim(-3, 103)
    ax.set_xlabel(x_label)
    ax.set_ylabel("success (%) with 95 % Wilson interval")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    _legend(ax, len(curves))
    return _finish(fig, path, provenance)


def _legend(ax, entries: int) -> None:
    if entries > 5:  # many methods: beside the plot, not over the curves
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1))
    else:
        ax.legend(fontsize=8)


def rate_bars(
    rates: dict[str, dict[str, Rate]],
    path: Path,
    provenance: str,
    title: str,
    per_seed: dict[str, dict[str, tuple[Rate, ...]]] | None = None,
) -> Path:
    """Grouped bars: success per suite (group) and method (bar), with 95 % Wilson intervals.

    ``rates``: method -> {suite: Rate}; a method without a suite has no bar there. ``per_seed``: method ->
    {suite: each training seed's rate}, drawn as dots on its bar, so that a pooled bar shows how far its seeds
    spread (a method of one seed is left out).
    """
    suites = list(dict.fromkeys(s for per in rates.values() for s in per))
    k = max(len(rates), 1)
    width = 0.8 / k
    fig, ax = plt.subplots(figsize=(min(12.0, max(6.4, 0.25 * len(suites) * k + 2.5)), 4.6))
    colors = series_colors(len(rates))
    for i, (name, per) in enumerate(rates.items()):
        xs = [j + (i - (k - 1) / 2) * width for j, s in enumerate(suites) if s in per]
        r = np.array([100 * per[s].rate for s in suites if s in per])
        lo = np.array([100 * per[s].interval[0] for s in suites if s in per])
        hi = np.array([100 * per[s].interval[1] for s in suites if s in per])
        ax.bar(xs, r, width, color=colors[i], label=name)
        ax.errorbar(xs, r, yerr=np.vstack([r - lo, hi - r]), fmt="none", capsize=2, ecolor="0.25", lw=0.8)
        seeds = (per_seed or {}).get(name, {})
        for x, s in zip(xs, [s for s in suites if s in per]):
            if s in seeds:
                ys = [100 * q.rate for q in seeds[s]]
                ax.plot([x] * len(ys), ys, "o", ms=3.5, mfc="white", mec="0.1", mew=0.8, zorder=3)
    slanted = len(suites) > 4  # long suite names overlap side by side
    ax.set_xticks(range(len(suites)), suites, rotation=35 if slanted else 0, ha="right" if slanted else "center")
    ax.set_ylim(0, 103)
    dots = " (dots: each training seed)" if per_seed and any(per_seed.get(n) for n in rates) else ""
    ax.set_ylabel("success (%) with 95 % Wilson interval")
    ax.set_title(title + dots)
    ax.grid(True, axis="y", alpha=0.3)
    _legend(ax, len(rates))
    return _finish(fig, path, provenance)


def axis_panels(
    panels: list[tuple[str, list[str], list[str]]],
    rates: dict[str, dict[str, Rate]],
    path: Path,
    provenance: str,
    title: str,
    target: float | None = None,
) -> Path:
    """One panel per disturbance axis: success per suite (group) and method (bar), with 95 % Wilson intervals;
    the axis's training-condition suites first, then its held-out ones (hatched, behind a dotted line).

    ``panels``: (axis name, in-distribution suites, held-out suites) drawn in that order; ``rates``: method ->
    {suite: Rate}, a method without a suite has no bar there; ``target``: a success rate (0-1) drawn as a line.
    """
    k = max(len(rates), 1)
    width = 0.8 / k
    colors = series_colors(len(rates))
    sizes = [len(inside) + len(held) for _, inside, held in panels]
    cols = min(len(panels), 3)
    rows = -(-len(panels) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.9 * rows + 0.4), squeeze=False)
    for ax, (axis_name, inside, held), n in zip(axes.flat, panels, sizes, strict=False):
        suites = [*inside, *held]
        for i, (name, per) in enumerate(rates.items()):
            js = [j for j, s in enumerate(suites) if s in per]
            xs = [j + (i - (k - 1) / 2) * width for j in js]
            r = np.array([100 * per[suites[j]].rate for j in js])
            lo = np.array([100 * per[suites[j]].interval[0] for j in js])
            hi = np.array([100 * per[suites[j]].interval[1] for j in js])
            hatch = ["//" if suites[j] in held else "" for j in js]
            bars = ax.bar(xs, r, width, color=colors[i], label=name, edgecolor="white", linewidth=0.3)
            for bar, h in zip(bars, hatch, strict=True):
                bar.set_hatch(h)
            ax.errorbar(xs, r, yerr=np.vstack([r - lo, hi - r]), fmt="none", capsize=1.5, ecolor="0.25", lw=0.7)
        if inside and held:
            ax.axvline(len(inside) - 0.5, color="0.4", ls=":", lw=1)
        if target is not None:
            ax.axhline(100 * target, color="0.5", ls="--", lw=0.8)
        short = [s.removeprefix("train_").removeprefix("heldout_") for s in suites]
        ax.set_xticks(range(n), short, rotation=35, ha="right", fontsize=7)
        ax.set_ylim(0, 103)
        ax.set_title(f"{axis_name}: trained | held out (hatched)", fontsize=9)
        ax.grid(True, axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(panels) :]:
        ax.set_visible(False)
    axes.flat[0].set_ylabel("success (%), 95 % Wilson")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper right", fontsize=7, ncol=min(k, 5))
    fig.suptitle(title, fontsize=10, x=0.01, ha="left")
    return _finish(fig, path, provenance)


def failures_by_phase(failures: dict[str, dict[str, dict[str, int]]], path: Path, provenance: str, title: str) -> Path:
    """Stacked bars: for each method (panel), failed episodes per furthest FSM phase, split by cause.

    ``failures``: method -> {phase name: {cause: count}}.
    """
    none = [name for name, per in failures.items() if not any(per.values())]
    failures = {name: per for name, per in failures.items() if any(per.values())} or {"(no failures)": {}}
    n = len(failures)
    cols = min(n, PANELS_PER_ROW)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols + 1.4, 3.8 * rows), squeeze=False, sharey=True)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    causes = sorted({c for per in failures.values() for counts in per.values() for c in counts})
    phases = list(robot.PHASE_NAMES)
    top = 1.0
    for ax, (name, per_phase) in zip(axes.flat[:n], failures.items(), strict=True):
        bottom = np.zeros(len(phases))
        for k, cause in enumerate(causes):
            h = np.array([per_phase.get(p, {}).get(cause, 0) for p in phases], dtype=float)
            ax.bar(range(len(phases)), h, bottom=bottom, color=f"C{k}")
            bottom += h
        top = max(top, bottom.max())
        ax.set_xticks(range(len(phases)), phases, fontsize=6, rotation=90)
        ax.set_title(f"{name} ({int(bottom.sum())} failures)", fontsize=9)
        ax.set_xlabel("furthest phase reached")
    for row in axes:
        row[0].set_ylabel("failed episodes")
    axes[0][0].set_ylim(0, top * 1.12)
    if causes:
        handles = [matplotlib.patches.Patch(color=f"C{k}", label=c) for k, c in enumerate(causes)]
        axes.flat[n - 1].legend(
            handles=handles,
            fontsize=7,
            title="failure cause",
            title_fontsize=7,
            loc="upper left",
            bbox_to_anchor=(1.01, 1),
        )
    fig.suptitle(title + (f" (no failures: {', '.join(none)})" if none else ""), fontsize=10)
    return _finish(fig, path, provenance)
