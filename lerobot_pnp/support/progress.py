"""Progress bars sized for a log as well as a terminal: ours, and stock LeRobot code run in process.

Ours (generation's episode bar, the fast trainer's epoch bar) redraw at ``redraw_interval_s(stream)``: twice a
second on a terminal, every ``LOG_INTERVAL_S`` into a log or a pipe, where each redraw is one more line of
carriage-return updates. ``log_friendly_tqdm`` is a tqdm bar with that interval.


LeRobot's ``eval_policy`` opens one tqdm bar per rollout batch (``Running rollout with at most N steps``) on top
of its ``Stepping through eval batches`` bar; the study and DAgger call it hundreds of times, so a terminal or
a log fills with bars. ``quiet_rollout_bars`` keeps the batches bar only, with tqdm's own options: shown on a
terminal, off when stderr is not one (``disable=None``), redrawn at most every few seconds (``mininterval``).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

MININTERVAL_S = 5.0
TERMINAL_INTERVAL_S = 0.5
LOG_INTERVAL_S = 15.0


def redraw_interval_s(stream) -> float:
    """Seconds between redraws of a bar written to ``stream``: a terminal is redrawn in place, a log appends."""
    return TERMINAL_INTERVAL_S if bool(getattr(stream, "isatty", lambda: False)()) else LOG_INTERVAL_S


def log_friendly_tqdm(stream=None, **kwargs):
    """``tqdm(**kwargs)`` on ``stream`` (default stderr) redrawn at most every ``redraw_interval_s(stream)``.

    Updates in between only count; pass ``refresh=False`` to ``set_postfix`` (its default forces a redraw).
    ``maxinterval`` is raised with it so that tqdm's monitor thread does not redraw sooner.
    """
    import sys

    from tqdm import tqdm

    stream = sys.stderr if stream is None else stream
    interval = redraw_interval_s(stream)
    return tqdm(file=stream, mininterval=interval, maxinterval=max(interval, 10.0), **kwargs)


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
