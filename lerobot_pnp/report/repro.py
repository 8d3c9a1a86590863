"""Whether two runs of the study agree: cell by cell and verdict by verdict, from their ``summary.json``.

**Cells.** A cell is one method's success on one suite, pooled over its training seeds (``success`` ->
suite -> method: ``rate``, ``n`` and ``per_seed``; the successes are ``rate * n``). Two runs' cells *differ
beyond their intervals* when the 95 % interval of the difference of their rates (B minus A) excludes 0. The
interval counts the training seeds as well as the episodes (``seed_difference_interval``: Welch's interval over
the seeds' rates joined with Newcombe's over the episodes, ``verdicts.difference_interval``), as the tables'
intervals do (``stats.seed_interval``): a rerun trains every seed anew, so a method whose seeds spread widely
can land far from its published rate without anything being wrong. Two runs of one config evaluate the same
eval seeds, so their episodes start alike; the interval for independent rates is then the wider one, and a cell
flagged by it differs the more surely. On the same code, CPU model and locked
dependencies the seeded stages are meant to give the same rates; on another CPU the trained nets differ in
their last bits and drift, and a cell may differ by chance: at 95 %, up to about one in twenty of the cells
whose runs agree in distribution.
A cell that only one run has is listed as missing from the other.

**Verdicts.** Each ``held_out_axes`` entry (one method on one axis) is given its verdict anew by
``verdicts.summary_verdict``, from its counts, in both runs, so that two summaries written under different
versions of the rule compare by today's rule. A verdict *changes* when its code differs, or when one run has
the entry and the other does not. The **headline** verdicts are ``HEADLINE_METHOD``'s (the recovering
planner's) on each held-out axis; a change there is what a rerun must not show.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.stats import Rate, t975
from lerobot_pnp.evaluation.verdicts import TEXT, difference_interval, summary_verdict

HEADLINE_METHOD = "recovering"


@dataclass(frozen=True)
class CellDiff:
    """One suite x method cell in both runs (None where a run lacks it) and the interval of B minus A."""

    suite: str
    method: str
    a: Rate | None
    b: Rate | None
    interval: tuple[float, float] | None = None

    @property
    def beyond(self) -> bool:
        """Whether the cell differs beyond its intervals (or is missing from one run)."""
        if self.interval is None:
            return True
        lo, hi = self.interval
        return lo > 0 or hi < 0


@dataclass(frozen=True)
class VerdictDiff:
    """One method's verdict on one axis in both runs (None where a run lacks the entry)."""

    axis: str
    method: str
    a: str | None
    b: str | None

    @property
    def changed(self) -> bool:
        return self.a != self.b

    @property
    def headline(self) -> bool:
        return self.method == HEADLINE_METHOD


@dataclass(frozen=True)
class Comparison:
    cells: list[CellDiff]
    verdicts: list[VerdictDiff]

    @property
    def cells_beyond(self) -> list[CellDiff]:
        return [c for c in self.cells if c.beyond]

    @property
    def verdicts_changed(self) -> list[VerdictDiff]:
        return [v for v in self.verdicts if v.changed]

    @property
    def headline_changed(self) -> bool:
        return any(v.changed and v.headline for v in self.verdicts)


def load_summary(path: Path) -> dict:
    """A study's ``summary.json``; a missing or unreadable file, or one without ``success``, is refused."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError) as e:
        raise ConfigError(f"cannot read a study summary from {path}: {e}") from None
    if not isinstance(data, dict) or not isinstance(data.get("success"), dict):
        raise ConfigError(f"{path} is not a study summary.json (it has no 'success' table)")
    return data


def seed_difference_interval(
    a: Rate, a_seeds: Sequence[float], b: Rate, b_seeds: Sequence[float]
) -> tuple[float, float]:
    """95 % interval of ``b.rate - a.rate`` for two rates pooled over training seeds, counting the seeds: Welch's
    interval over the seeds' rates (``a_seeds``, ``b_seeds``; Welch-Satterthwaite degrees of freedom, rounded
    down), joined with Newcombe's over the episodes (``difference_interval``). With fewer than two seeds on a
    side, Newcombe's alone."""
    lo, hi = difference_interval(a, b)
    if min(len(a_seeds), len(b_seeds)) < 2:
        return lo, hi
    var = [_variance(r) / len(r) for r in (a_seeds, b_seeds)]
    se = math.sqrt(sum(var))
    if se == 0:
        return lo, hi
    dof = sum(var) ** 2 / sum(v**2 / (len(r) - 1) for v, r in zip(var, (a_seeds, b_seeds)) if v > 0)
    half = t975(max(1, math.floor(dof))) * se
    d = b.rate - a.rate
    return max(-1.0, min(lo, d - half)), min(1.0, max(hi, d + half))


def _variance(rates: Sequence[float]) -> float:
    mean = sum(rates) / len(rates)
    return sum((r - mean) ** 2 for r in rates) / (len(rates) - 1)


def _rate(cell: dict) -> Rate:
    n = int(cell["n"])
    return Rate(round(cell["rate"] * n), n)


def compare_cells(a: dict, b: dict) -> list[CellDiff]:
    """Every suite x method cell of either summary, in A's order then B's additions."""
    out = []
    suites = list(a["success"]) + [s for s in b["success"] if s not in a["success"]]
    for suite in suites:
        row_a, row_b = a["success"].get(suite, {}), b["success"].get(suite, {})
        for method in list(row_a) + [m for m in row_b if m not in row_a]:
            ra = _rate(row_a[method]) if method in row_a else None
            rb = _rate(row_b[method]) if method in row_b else None
            interval = None
            if ra and rb:
                interval = seed_difference_interval(
                    ra, row_a[method].get("per_seed", []), rb, row_b[method].get("per_seed", [])
                )
            out.append(CellDiff(suite, method, ra, rb, interval))
    return out


def _verdicts(summary: dict) -> dict[tuple[str, str], str]:
    return {(e["axis"], e["method"]): summary_verdict(e).code for e in summary.get("held_out_axes", [])}


def compare_verdicts(a: dict, b: dict) -> list[VerdictDiff]:
    """Every axis x method verdict of either summary, each recomputed by ``summary_verdict``."""
    va, vb = _verdicts(a), _verdicts(b)
    keys = list(va) + [k for k in vb if k not in va]
    return [VerdictDiff(axis, method, va.get((axis, method)), vb.get((axis, method))) for axis, method in keys]


def compare(a: dict, b: dict) -> Comparison:
    return Comparison(compare_cells(a, b), compare_verdicts(a, b))


def _pct(rate: Rate | None) -> str:
    return "missing" if rate is None else f"{100 * rate.rate:.1f} % (n {rate.n})"


def _verdict_text(code: str | None) -> str:
    return "missing" if code is None else TEXT[code]


def summary_line(c: Comparison) -> str:
    headline = sum(v.changed and v.headline for v in c.verdicts)
    return (
        f"{len(c.cells)} cells compared, {len(c.cells_beyond)} differ beyond their intervals; "
        f"{len(c.verdicts)} verdicts compared, {len(c.verdicts_changed)} changed "
        f"({headline} of the {HEADLINE_METHOD} planner's headline verdicts)."
    )


def render(c: Comparison, label_a: str = "A", label_b: str = "B", all_cells: bool = False) -> str:
    """The comparison as markdown: the one-line summary, then the cells that differ beyond their intervals
    (every cell with ``all_cells``) and every verdict with whether it changed."""
    lines = [summary_line(c), "", f"A: {label_a}  ", f"B: {label_b}", ""]
    cells = c.cells if all_cells else c.cells_beyond
    if cells:
        lines += ["| suite | method | A | B | B - A [95 %] | beyond |", "|---|---|---|---|---|---|"]
        for d in cells:
            diff = "-"
            if d.interval is not None:
                lo, hi = d.interval
                diff = f"{100 * (d.b.rate - d.a.rate):+.1f} [{100 * lo:+.1f}, {100 * hi:+.1f}]"
            lines.append(
                f"| {d.suite} | {d.method} | {_pct(d.a)} | {_pct(d.b)} | {diff} | {'yes' if d.beyond else 'no'} |"
            )
        lines.append("")
    if c.verdicts:
        lines += ["| axis | method | A | B | changed |", "|---|---|---|---|---|"]
        for v in c.verdicts:
            mark = ("**yes (headline)**" if v.headline else "yes") if v.changed else "no"
            name = f"**{v.method}**" if v.headline else v.method
            lines.append(f"| {v.axis} | {name} | {_verdict_text(v.a)} | {_verdict_text(v.b)} | {mark} |")
    return "\n".join(lines).rstrip() + "\n"
