"""Success rates with 95 % intervals (Wilson; pooled over training seeds, counting the seeds) and paired
comparisons of two methods on the same seeds.

Every method is evaluated on the same seeded episodes, so two methods can be compared episode by episode:
only the discordant pairs (one succeeds where the other fails) carry information, and under "no difference"
each discordant pair goes either way with probability 1/2 (exact McNemar = two-sided sign test). This is far
more sensitive than checking whether two independent intervals overlap.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

Z95 = 1.959963984540054


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval for a binomial proportion (good at 0 % and 100 %, unlike the normal one)."""
    if n <= 0:
        raise ValueError(f"wilson_interval needs n >= 1 trials, got {n}")
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be in [0, {n}], got {successes}")
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    lo = 0.0 if successes == 0 else max(0.0, centre - half)
    hi = 1.0 if successes == n else min(1.0, centre + half)
    return lo, hi


# Student's t at 0.975 for 1-10 degrees of freedom; above, the Cornish-Fisher expansion (``t975``).
_T975 = (12.706204736, 4.302652730, 3.182446305, 2.776445105, 2.570581836, 2.446911851, 2.364624252, 2.306004135,
         2.262157163, 2.228138852)  # fmt: skip


def t975(dof: int) -> float:
    """The 97.5 % quantile of Student's t with ``dof`` degrees of freedom (the half-width factor of a 95 %
    interval): a table up to 10, the Cornish-Fisher expansion in ``1/dof`` beyond (error below 1e-4)."""
    if dof < 1:
        raise ValueError(f"t975 needs dof >= 1, got {dof}")
    if dof <= len(_T975):
        return _T975[dof - 1]
    z = Z95
    return (
        z
        + (z**3 + z) / (4 * dof)
        + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * dof**2)
        + (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / (384 * dof**3)
    )


def seed_interval(pooled: Rate, seed_rates: Sequence[float]) -> tuple[float, float]:
    """95 % interval of a rate pooled over training seeds that counts the seeds as well as the episodes.

    The Wilson interval of the pooled episodes says how well the evaluation measured these trained networks; a
    rerun trains them anew (another machine's floats, other seeds) and can land elsewhere when the seeds spread
    more than their episodes explain. Here the pooled rate +- t(k-1) s / sqrt(k) over the k seeds' rates (s: their
    standard deviation, which carries both the training's and the episodes' variation), joined with the Wilson
    interval, so that it is never narrower than the episodes allow. One seed: the Wilson interval."""
    lo, hi = pooled.interval
    k = len(seed_rates)
    if k < 2:
        return lo, hi
    mean = sum(seed_rates) / k
    sd = math.sqrt(sum((r - mean) ** 2 for r in seed_rates) / (k - 1))
    half = t975(k - 1) * sd / math.sqrt(k)
    return max(0.0, min(lo, pooled.rate - half)), min(1.0, max(hi, pooled.rate + half))


@dataclass(frozen=True)
class Rate:
    """``successes`` out of ``n`` with its 95 % Wilson interval."""

    successes: int
    n: int

    @property
    def rate(self) -> float:
        return self.successes / self.n

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.successes, self.n)

    def __str__(self) -> str:
        lo, hi = self.interval
        return f"{100 * self.rate:.1f}% [{100 * lo:.1f}, {100 * hi:.1f}]"

    @classmethod
    def of(cls, outcomes: Sequence[bool]) -> Rate:
        """The rate of a list of episode outcomes (True = success)."""
        return cls(int(sum(bool(o) for o in outcomes)), len(outcomes))


# Up to this many trials (episodes of both samples, or discordant pairs) a tail is summed in exact integers; beyond,
# in floating point from its largest term outwards (relative error about 1e-10), so that its cost grows linearly
# with the episodes instead of with their square.
EXACT_TRIALS = 10_000


def below_p(a: Rate, b: Rate) -> float:
    """One-sided exact (Fisher) p-value that ``b`` is below ``a`` by chance: for two independent samples (two
    suites, or two conditions), the probability under "same rate" that ``b`` gets ``b.successes`` or fewer of
    all the successes (the hypergeometric lower tail)."""
    total, k = a.n + b.n, a.successes + b.successes
    low, high = max(0, k - a.n), min(k, b.n)
    top = min(b.successes, high)
    if total > EXACT_TRIALS:
        mode = (b.n + 1) * (k + 1) // (total + 2)
        peak = min(max(mode, low), top)
        log_peak = _log_comb(k, peak) + _log_comb(total - k, b.n - peak) - _log_comb(total, b.n)

        def ratio(i: int) -> float:
            return (k - i) * (b.n - i) / ((i + 1) * (total - k - b.n + i + 1))

        return min(1.0, math.exp(log_peak) * _sum_from_peak(peak, low, top, ratio))
    left, right = math.comb(k, low), math.comb(total - k, b.n - low)  # C(k, i), C(total - k, b.n - i) at i = low
    tail = 0
    for i in range(low, top + 1):
        tail += left * right
        left = left * (k - i) // (i + 1)
        right = right * (b.n - i) // (total - k - b.n + i + 1) if i < top else right
    return min(1.0, tail / math.comb(total, b.n))


def sign_test_p(wins: int, losses: int) -> float:
    """Two-sided exact binomial test of ``wins`` vs ``losses`` under p = 1/2 (ties already removed)."""
    n = wins + losses
    if n == 0:
        return 1.0
    k = min(wins, losses)
    if n > EXACT_TRIALS:

        def ratio(i: int) -> float:
            return (n - i) / (i + 1)

        return min(1.0, 2 * math.exp(_log_comb(n, k) - n * math.log(2)) * _sum_from_peak(k, 0, k, ratio))
    term, tail = 1, 0  # C(n, i) for i = 0 .. k, in exact integers
    for i in range(k + 1):
        tail += term
        term = term * (n - i) // (i + 1)
    return min(1.0, 2 * tail / 2**n)


def _log_comb(n: int, k: int) -> float:
    return math.lgamma(n + 1) - math.lgamma(k + 1) - math.lgamma(n - k + 1)


def _sum_from_peak(peak: int, lo: int, hi: int, ratio) -> float:
    """The terms ``t_i`` for ``i`` in [lo, hi] summed relative to ``t_peak`` (the largest of them), given
    ``ratio(i) = t_(i+1) / t_i``: outwards from the peak on both sides, each side stopped once its terms no
    longer change the sum (the binomial's and the hypergeometric's terms fall faster than geometrically away
    from their mode)."""
    total, term = 1.0, 1.0
    for i in range(peak - 1, lo - 1, -1):
        term /= ratio(i)
        total += term
        if term < total * 1e-20:
            break
    term = 1.0
    for i in range(peak, hi):
        term *= ratio(i)
        total += term
        if term < total * 1e-20:
            break
    return total


@dataclass(frozen=True)
class PairedComparison:
    """Method A vs method B on the same seeds: discordant counts and the exact McNemar p-value."""

    n: int  # paired episodes
    a_only: int  # A succeeded, B failed
    b_only: int  # B succeeded, A failed
    p_value: float

    @property
    def difference(self) -> float:
        """Success rate of A minus that of B."""
        return (self.a_only - self.b_only) / self.n

    def significant(self, alpha: float = 0.05) -> bool:
        return self.p_value < alpha

    def __str__(self) -> str:
        return f"{100 * self.difference:+.1f} pts ({self.a_only} vs {self.b_only} discordant, p={self.p_value:.2g})"


def paired_comparison(a: dict[int, bool], b: dict[int, bool]) -> PairedComparison:
    """Compare two methods episode by episode on the seeds both were evaluated on (``{seed: success}``)."""
    seeds = sorted(set(a) & set(b))
    if not seeds:
        raise ValueError("paired_comparison: the two methods share no evaluation seed")
    a_only = sum(1 for s in seeds if a[s] and not b[s])
    b_only = sum(1 for s in seeds if b[s] and not a[s])
    return PairedComparison(len(seeds), a_only, b_only, sign_test_p(a_only, b_only))


def paired_difference_interval(both: int, a_only: int, b_only: int, neither: int) -> tuple[float, float]:
    """95 % interval of rate(A) - rate(B) from paired outcomes (Newcombe 1998, method 10: each rate's Wilson
    interval, combined with the correlation of the pairs). Same seeds make the pairs: an interval for two
    independent rates would be far wider than what the seeds allow."""
    n = both + a_only + b_only + neither
    if n <= 0:
        raise ValueError("paired_difference_interval needs at least one pair")
    p1, p2 = (both + a_only) / n, (both + b_only) / n
    l1, u1 = wilson_interval(both + a_only, n)
    l2, u2 = wilson_interval(both + b_only, n)
    margins = (both + a_only) * (b_only + neither) * (both + b_only) * (a_only + neither)
    phi = (both * neither - a_only * b_only) / math.sqrt(margins) if margins else 0.0
    d = p1 - p2
    below = math.sqrt(max(0.0, (p1 - l1) ** 2 - 2 * phi * (p1 - l1) * (u2 - p2) + (u2 - p2) ** 2))
    above = math.sqrt(max(0.0, (u1 - p1) ** 2 - 2 * phi * (u1 - p1) * (p2 - l2) + (p2 - l2) ** 2))
    return max(-1.0, d - below), min(1.0, d + above)


def chi2_sf(x: float, dof: int) -> float:
    """The chi-square distribution's survival function P(X >= x) for a whole number of degrees of freedom, in
    closed form (the series of the regularised upper incomplete gamma at half-integer shape)."""
    if dof < 1:
        raise ValueError(f"chi2_sf needs dof >= 1, got {dof}")
    if x <= 0:
        return 1.0
    half = x / 2
    if dof % 2 == 0:
        term, total = 1.0, 1.0
        for i in range(1, dof // 2):
            term *= half / i
            total += term
        return min(1.0, math.exp(-half) * total)
    term, total = 1.0, 0.0
    for i in range(1, (dof - 1) // 2 + 1):
        total += term
        term *= x / (2 * i + 1)
    return min(1.0, math.erfc(math.sqrt(half)) + math.sqrt(2 * x / math.pi) * math.exp(-half) * total)


@dataclass(frozen=True)
class SeedAgreement:
    """Whether a method's training seeds share one success rate: Pearson's chi-square test of homogeneity of
    their counts (k seeds x success / failure). Pooling seeds into one Wilson interval treats every episode as a
    draw from one rate; where the seeds differ beyond evaluation noise, the pooled interval describes these
    seeds, not the rate a new training seed gets."""

    per_seed: tuple[Rate, ...]
    chi2: float
    dof: int
    p_value: float

    def differ(self, alpha: float = 0.05) -> bool:
        return self.p_value < alpha

    def to_json(self, alpha: float = 0.05) -> dict:
        """``compare.json``'s cell: each seed's rate, the statistic, its degrees of freedom, p and the verdict."""
        return {"per_seed": [r.rate for r in self.per_seed], "chi2": self.chi2, "dof": self.dof, "p": self.p_value,
                "differ": self.differ(alpha)}  # fmt: skip


def seed_agreement(per_seed: Sequence[Rate]) -> SeedAgreement:
    """The chi-square test of homogeneity over two or more training seeds' rates (``SeedAgreement``)."""
    if len(per_seed) < 2:
        raise ValueError(f"seed_agreement needs two or more training seeds, got {len(per_seed)}")
    wins, n = sum(r.successes for r in per_seed), sum(r.n for r in per_seed)
    p = wins / n
    if p in (0.0, 1.0):  # every seed at 0 % or every seed at 100 %: nothing varies
        return SeedAgreement(tuple(per_seed), 0.0, len(per_seed) - 1, 1.0)
    chi2 = sum((r.successes - r.n * p) ** 2 / (r.n * p * (1 - p)) for r in per_seed)
    return SeedAgreement(tuple(per_seed), chi2, len(per_seed) - 1, chi2_sf(chi2, len(per_seed) - 1))
