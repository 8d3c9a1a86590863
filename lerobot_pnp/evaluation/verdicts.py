"""The one verdict rule of the held-out protocol: non-inferiority with a stated margin.

Whether recovery generalises along an axis is read from the difference *held out minus in distribution* of
one method's success, and its 95 % interval (Newcombe's hybrid score interval for two independent rates,
built from their Wilson intervals; the two sides are different suites, so their episodes do not pair):

- **no verdict** when the method is below ``TARGET`` in distribution: there is no recovery to generalise;
- **generalises** when the interval's lower bound lies above ``-MARGIN``: held out is at most ``MARGIN``
  worse, at 95 %;
- **does not generalise** when the interval's upper bound lies below ``-MARGIN``: held out is worse by more
  than ``MARGIN``, at 95 %;
- **undecided** otherwise, with the number of episodes per side that would decide it at the observed rates.

The margin is 5 points of success. It is the difference a reader of the benchmark can act on: the protocol's
in-distribution bar is 90 %, and a method that loses up to 5 points beyond its training disturbances still
recovers in 85 % of the held-out episodes or more. It is also the smallest difference the protocol's episode
counts resolve: near 95 %, a side of a few hundred episodes has a Wilson interval a few points wide. Unlike a
test of "not shown to be worse", the rule does not flip when one episode near 100 % changes: the interval moves
by a fraction of a point, and only a difference near the margin is left undecided.

``lerobot-pnp compare`` states its run-versus-reference verdict by the same margin on a paired interval
(``margin_call``), and the study, ``compare`` and the leaderboard all take their axis verdicts from
``axis_verdict``.
"""

from __future__ import annotations

from dataclasses import dataclass

from lerobot_pnp.evaluation.stats import Rate, wilson_interval

TARGET = 0.9  # the in-distribution success an axis verdict needs
MARGIN = 0.05  # how much worse held out may be and still generalise (a fraction of success)
VERDICTS = ("generalises", "does_not_generalise", "undecided", "no_verdict")
TEXT = {
    "generalises": "generalises",
    "does_not_generalise": "does not generalise",
    "undecided": "undecided",
    "no_verdict": "no verdict",
}
MARK = {"generalises": "✓", "does_not_generalise": "✗", "undecided": "?", "no_verdict": "○"}
MAX_SCALE = 100  # episodes_to_decide looks no further than this many times the episodes measured


def difference_interval(inside: Rate, outside: Rate) -> tuple[float, float]:
    """95 % interval of ``outside.rate - inside.rate`` (Newcombe's hybrid score method, independent rates)."""
    p1, p2 = inside.rate, outside.rate
    l1, u1 = wilson_interval(inside.successes, inside.n)
    l2, u2 = wilson_interval(outside.successes, outside.n)
    d = p2 - p1
    lo = d - ((p2 - l2) ** 2 + (u1 - p1) ** 2) ** 0.5
    hi = d + ((u2 - p2) ** 2 + (p1 - l1) ** 2) ** 0.5
    return max(-1.0, lo), min(1.0, hi)


def margin_call(lo: float, hi: float, margin: float = MARGIN) -> str:
    """Where a difference's interval lies against ``-margin``: "above" (not worse by the margin), "below"
    (worse by more than the margin) or "across" (the interval holds ``-margin``)."""
    if lo > -margin:
        return "above"
    if hi < -margin:
        return "below"
    return "across"


@dataclass(frozen=True)
class Verdict:
    """An axis verdict with what it rests on: the difference (held out minus in distribution) and its interval,
    and for an undecided one the episodes per side that would decide it at the observed rates."""

    code: str  # one of VERDICTS
    difference: float
    interval: tuple[float, float]
    episodes_to_decide: int | None = None

    @property
    def text(self) -> str:
        return TEXT[self.code]

    def short(self) -> str:
        """The verdict with its difference and interval in points, for a table's cell."""
        lo, hi = self.interval
        return f"{self.text} ({100 * self.difference:+.1f} [{100 * lo:+.1f}, {100 * hi:+.1f}])"

    def phrase(self) -> str:
        """The verdict with its difference, as a page states it (``undecided`` adds what would decide it)."""
        lo, hi = self.interval
        diff = f"{100 * self.difference:+.1f} points [{100 * lo:+.1f}, {100 * hi:+.1f}]"
        if self.code == "no_verdict":
            return f"no verdict (below {100 * TARGET:.0f} % in distribution); {diff}"
        tail = ""
        if self.code == "undecided":
            tail = (
                f"; about {self.episodes_to_decide} episodes a side would decide it"
                if self.episodes_to_decide
                else "; the rates differ by about the margin: more episodes would not decide it soon"
            )
        return f"{self.text} ({diff}, margin {100 * MARGIN:.0f}){tail}"


def episodes_to_decide(inside: Rate, outside: Rate, margin: float = MARGIN) -> int | None:
    """The episodes per side (both sides the same count) at which the observed rates would give a decided
    verdict, or None when even ``MAX_SCALE`` times the larger side's episodes would not."""
    base = max(inside.n, outside.n)
    for factor in range(2, MAX_SCALE + 1):
        n = base * factor
        a = Rate(round(inside.rate * n), n)
        b = Rate(round(outside.rate * n), n)
        if margin_call(*difference_interval(a, b), margin) != "across":
            return n
    return None


def axis_verdict(inside: Rate, outside: Rate, margin: float = MARGIN, target: float = TARGET) -> Verdict:
    """The held-out verdict for one method on one axis (each side pooled over its suites and seeds)."""
    lo, hi = difference_interval(inside, outside)
    diff = outside.rate - inside.rate
    if inside.rate < target:
        return Verdict("no_verdict", diff, (lo, hi))
    call = margin_call(lo, hi, margin)
    if call == "above":
        return Verdict("generalises", diff, (lo, hi))
    if call == "below":
        return Verdict("does_not_generalise", diff, (lo, hi))
    return Verdict("undecided", diff, (lo, hi), episodes_to_decide(inside, outside, margin))


def summary_verdict(entry: dict) -> Verdict:
    """The rule's verdict on a ``summary.json`` ``held_out_axes`` entry, from its counts: one rule on every page,
    whichever rule the study that wrote the summary applied."""
    inside, outside = entry["in_distribution"], entry["held_out"]
    return axis_verdict(Rate(inside["successes"], inside["n"]), Rate(outside["successes"], outside["n"]))
