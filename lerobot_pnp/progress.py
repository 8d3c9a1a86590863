"""Progress bars of stock LeRobot code run in process, sized for a log rather than a terminal.

LeRobot's ``eval_policy`` opens one tqdm bar per rollout batch (``Running rollout with at most N steps``) on top
of its ``Stepping through eval batches`` bar; the study and DAgger call it hundreds of times, so a terminal or
a log fills with bars. ``quiet_rollout_bars`` keeps the batches bar only, with tqdm's own options: shown on a
terminal, off when stderr is not one (``disable=None``), redrawn at most every few seconds (``mininterval``).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

MININTERVAL_S = 5.0


@contextlib.contextmanager
def quiet_rollout_bars() -> Iterator[None]:
    """Within the block, ``lerobot.scripts.lerobot_eval``'s bars: the per-rollout bar off, the batches bar
    aggregated (tqdm hides it when stderr is no terminal). The module's own ``trange`` is restored on exit."""
    from unittest import mock

    from lerobot.scripts import lerobot_eval
    from tqdm import trange

    def calm_trange(*args, desc: str = "", disable: bool = False, **kwargs):
        if desc.startswith("Running rollout"):
            disable = True
        else:
            disable = True if disable else None  # None: tqdm shows the bar on a terminal only
            kwargs["mininterval"] = max(kwargs.get("mininterval", 0.1), MININTERVAL_S)
        return trange(*args, desc=desc, disable=disable, **kwargs)

    with mock.patch.object(lerobot_eval, "trange", calm_trange):
        yield
