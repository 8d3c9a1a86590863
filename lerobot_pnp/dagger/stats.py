"""Success rates with Wilson 95 % score intervals (exact enough at 200 episodes, sane at 0 % and 100 %)."""

from __future__ import annotations

import math


def wilson(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval ``(low, high)`` of a binomial proportion; ``(0, 1)`` for ``n == 0``."""
    if n <= 0:
        return 0.0, 1.0
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def rate_cell(successes: int, n: int) -> str:
    """``"98.5 % [95.7, 99.5]"``: the rate and its Wilson 95 % interval, in percent."""
    lo, hi = wilson(successes, n)
    return f"{100 * successes / max(n, 1):.1f} % [{100 * lo:.1f}, {100 * hi:.1f}]"
