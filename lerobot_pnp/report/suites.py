"""Named evaluation suites: each is a set of changes to the task a method was trained on.

A suite never restates the whole task: it lists the env-config fields it changes (``BaxterPnPEnvConfig``
field names), applied on top of the task recorded with the training data, so the same suite means the same
thing for a policy trained on ``paper`` and one trained on ``full`` (e.g. "random yaw" widens the yaw range;
whether the policy observes yaw is a property of its training task).

A suite may have several parts evaluated one after the other on consecutive seed blocks (no suite of the
catalogue needs more than one since the env can exclude an inner box: the inside strip and the outside ring
are one box minus another, see ``band``). Every method sees exactly the same seeds.

Perturbations that need room to recover (missed grasp, drop, displacement) raise the keyframe budget
to ``RECOVERY_BUDGET`` keyframe steps: with the paper's 10 steps not even the expert could recover.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from lerobot_pnp.env_config import PAPER_TASK, BaxterPnPEnvConfig
from lerobot_pnp.errors import ConfigError

RECOVERY_BUDGET = 20  # keyframe steps: two full pick-and-place attempts
EDGE_WIDTH = 0.03  # m: width of the inside strip and of the outside ring


@dataclass(frozen=True)
class Suite:
    """A named evaluation condition: env-config ``changes`` per part, with the share of episodes of each."""

    name: str
    description: str
    parts: tuple[dict[str, Any], ...] = ({},)
    group: str = ""  # suites of one sweep share a group (a robustness curve)
    x: float | None = None  # the swept value in that group
    x_label: str = ""

    def part_episodes(self, n_episodes: int) -> list[int]:
        """Episodes of each part (as equal as possible, summing to ``n_episodes``)."""
        k = len(self.parts)
        return [n_episodes // k + (1 if i < n_episodes % k else 0) for i in range(k)]

    def env_configs(self, base: BaxterPnPEnvConfig) -> list[BaxterPnPEnvConfig]:
        """The env config of each part: ``base`` (the training task) with this suite's changes."""
        out = []
        for changes in self.parts:
            try:  # with_changes lets the episode length follow a changed keyframe budget
                out.append(base.with_changes(**changes))
            except ConfigError as err:
                raise ConfigError(f"suite {self.name!r}: {err}") from None
        return out


def band(low, high, width: float, outside: bool) -> dict[str, Any]:
    """The env changes that place the object uniformly in the band of ``width`` along the edge of the box
    ``low..high``: just inside the edge (``outside=False``: interpolation at the border of the data) or the ring
    just beyond it (extrapolation). One box minus an excluded inner box (the env's rejection sampling), so the
    band is sampled exactly uniformly."""
    box = tuple(map(float, low)), tuple(map(float, high))
    outer, inner = (_grow(*box, width), box) if outside else (box, _grow(*box, -width))
    return {
        "object_low": outer[0],
        "object_high": outer[1],
        "object_exclude_low": inner[0],
        "object_exclude_high": inner[1],
    }


def _grow(low, high, d: float):
    """The box ``low..high`` with every side moved out by ``d`` (in, for ``d < 0``)."""
    return tuple(_r(v - d) for v in low), tuple(_r(v + d) for v in high)


def _r(v: float) -> float:
    return round(float(v), 4)


def _sweep(group: str, x_label: str, field_name: str, values, extra: dict | None = None, desc: str = "") -> list:
    return [
        Suite(
            f"{group}_{v:g}",
            desc.format(v=v),
            ({field_name: v, **(extra or {})},),
            group=group,
            x=float(v),
            x_label=x_label,
        )
        for v in values
    ]


def _catalogue() -> dict[str, Suite]:
    low, high = PAPER_TASK["object_low"], PAPER_TASK["object_high"]
    recover = {"keyframe_budget": RECOVERY_BUDGET}
    suites = [
        Suite("nominal", "unseen object positions, the training task unchanged"),
        Suite(
            "slack",
            f"unseen object positions with a {RECOVERY_BUDGET}-keyframe budget: room for repeated or extra steps",
            (recover,),
        ),
        Suite(
            "edge_strip",
            f"object within {100 * EDGE_WIDTH:.0f} cm inside the edge of the training box",
            (band(low, high, EDGE_WIDTH, outside=False),),
        ),
        Suite(
            "outside_ring",
            f"object up to {100 * EDGE_WIDTH:.0f} cm outside the training box (extrapolation)",
            (band(low, high, EDGE_WIDTH, outside=True),),
        ),
        *_sweep(
            "nudge",
            "nudge radius (cm)",
            "nudge_max",
            (0.01, 0.02, 0.03, 0.05),
            desc="object pushed up to {v} m after the first keyframe, before the grasp",
        ),
        *_sweep(
            "obs_noise",
            "object noise std (mm)",
            "obs_noise_object",
            (0.002, 0.005, 0.01),
            desc="Gaussian noise of std {v} m on the observed object position",
        ),
        Suite("latency", "observations one step old", ({"obs_latency": 1},)),
        Suite(
            "grasp_miss",
            "the object slides out of the open gripper at the grasp",
            ({"grasp_miss_prob": 1.0, **recover},),
        ),
        Suite("drop", "the object is knocked out of the gripper in transport", ({"drop_prob": 1.0, **recover},)),
        Suite("displace", "the object is moved 4-8 cm after it was released", ({"displace_prob": 1.0, **recover},)),
        Suite("random_yaw", "object yaw uniform in [-pi, pi)", ({"yaw_range": (-math.pi, math.pi)},)),
        Suite(
            "random_place",
            "place target drawn from the full preset's region",
            ({"place_low": (0.50, -0.20), "place_high": (0.70, -0.05)},),
        ),
    ]
    return {s.name: s for s in suites}


SUITES: dict[str, Suite] = _catalogue()


def get_suites(names: list[str]) -> list[Suite]:
    """The suites named (``"nudge"`` selects the whole nudge sweep); unknown names are a ConfigError."""
    groups = {s.group for s in SUITES.values() if s.group}
    out: list[Suite] = []
    for name in names:
        if name in SUITES:
            out.append(SUITES[name])
        elif name in groups:
            out += [s for s in SUITES.values() if s.group == name]
        else:
            raise ConfigError(f"unknown evaluation suite {name!r}; valid: {sorted(SUITES) + sorted(groups)}")
    unique = {s.name: s for s in out}  # a suite named twice is run once
    return list(unique.values())
