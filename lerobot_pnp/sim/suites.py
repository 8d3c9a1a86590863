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

DAgger evaluates and rolls out on the ``quiet*`` suites: every perturbation of the training task switched off
(``quiet``), then one event at probability 1 or one observation fault on top, with the keyframe budget as
trained. ``nominal`` (the training task unchanged) is what DAgger called ``full``.
"""

from __future__ import annotations

import math
from typing import Any

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.presets import FULL_TASK, PAPER_TASK
from lerobot_pnp.sim.disturbances import KINDS
from lerobot_pnp.sim.suite_types import Axis, Suite
from lerobot_pnp.sim.visual_suites import VISUAL_AXES, visual_suites

__all__ = ["ALL_AXES", "HELD_OUT_AXES", "SUITES", "VISUAL_AXES", "Axis", "Suite", "get_suites"]

RECOVERY_BUDGET = 20  # keyframe steps: two full pick-and-place attempts
EDGE_WIDTH = 0.03  # m: width of the inside strip and of the outside ring


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


def _sweep(
    group: str, x_label: str, field_name: str, values, extra: dict | None = None, desc: str = "", x_scale: float = 1.0
) -> list:
    return [
        Suite(
            f"{group}_{v:g}",
            desc.format(v=v),
            ({field_name: v, **(extra or {})},),
            group=group,
            x=float(v),
            x_label=x_label,
            x_scale=x_scale,
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
            x_scale=100,
        ),
        *_sweep(
            "obs_noise",
            "object noise std (mm)",
            "obs_noise_object",
            (0.002, 0.005, 0.01),
            desc="Gaussian noise of std {v} m on the observed object position",
            x_scale=1000,
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
    return {s.name: s for s in [*suites, *_held_out_protocol(), *_quiet_suites(), *visual_suites()]}


# Every perturbation off: no events (nudge, missed grasp, drop, displacement), exact and current observations.
_QUIET: dict[str, Any] = {
    k: PAPER_TASK[k]
    for k in (
        "nudge_max", "grasp_miss_prob", "drop_prob", "displace_prob",
        "obs_noise_object", "obs_noise_joints", "obs_bias_object", "obs_latency",
    )
}  # fmt: skip
_OBS_NOISE = {"obs_noise_object": 0.003, "obs_noise_joints": 0.005}


def _quiet_suites() -> list[Suite]:
    """DAgger's suites: the training task with every perturbation off, plus one thing at a time."""
    one = {
        "quiet_grasp_miss": ("a missed grasp in every episode", {"grasp_miss_prob": 1.0}),
        "quiet_drop": ("a drop in transport in every episode", {"drop_prob": 1.0}),
        "quiet_nudge_0.03": ("object pushed up to 0.03 m before the grasp", {"nudge_max": 0.03}),
        "quiet_displace": ("the object moved after its release in every episode", {"displace_prob": 1.0}),
        "quiet_noise_latency": (
            "noisy, biased observations one step old",
            {**_OBS_NOISE, "obs_bias_object": 0.003, "obs_latency": 1},
        ),
        # quiet_noise_latency's parts, one at a time (to tell which one a policy fails on)
        "quiet_noise": ("Gaussian noise on the observed object and joints", _OBS_NOISE),
        "quiet_bias": ("a constant bias on the observed object position", {"obs_bias_object": 0.003}),
        "quiet_latency": ("observations one step old", {"obs_latency": 1}),
    }
    quiet = Suite("quiet", "the training task with every perturbation off (events and observation faults)", (_QUIET,))
    return [quiet, *(Suite(name, f"{desc}, every other perturbation off", ({**_QUIET, **changes},))
                     for name, (desc, changes) in one.items())]  # fmt: skip


# ---------------------------------------------------------------------------------------------- held-out protocol
def _kind(kind: str, **changes) -> dict[str, Any]:
    """Every field of one perturbation kind, from the training condition, with ``changes``; the kind fires in
    every episode and the budget leaves room for one more attempt per event and a spare one (the training task's
    own perturbations still happen). Stating every field makes the
    suite mean the same on top of any training task."""
    fields_ = {k: FULL_TASK[k] for k in FULL_TASK if k.startswith(f"{kind}_") or k.startswith("landing_")}
    out = {**fields_, f"{kind}_prob": 1.0, **changes}
    events = out[f"{kind}_max_events"]
    return {**out, "keyframe_budget": 10 * (events + 2)}


_LATE = (0.5, 1.0)  # the second half of each window (training: the first half)
# Kinds whose moment within the window a policy can tell apart. A displacement's window is the rise of the
# place retract, and the episode ends at the first successful step: in keyframe control the retract is one step,
# so the next observation is the same whenever in it the object moved; in dense control the pending displacement
# fires at the first successful step, whatever its window. A "late displacement" suite gave every method the
# same episodes as ``train_displace``, so it is not a held-out condition and is not in the catalogue.
_TIMED_KINDS = ("grasp_miss", "drop")
_TRAIN_LATENCY = {"obs_latency": 0, "obs_latency_max": 1, "obs_latency_jitter": 0.0}  # the recovering recipe's


def _held_out_protocol() -> list[Suite]:
    far = {"drop": (0.15, 0.30), "displace": (0.10, 0.20)}
    suites = [Suite(f"train_{k}", f"{k} as in training: the full preset's distribution", (_kind(k),)) for k in KINDS]
    suites += [
        Suite(
            f"heldout_late_{k}",
            f"{k} in the second half of its window (trained: the first)",
            (_kind(k, **{f"{k}_window": _LATE}),),
        )
        for k in _TIMED_KINDS
    ]
    suites += [
        Suite(
            f"heldout_far_{k}",
            f"{k} moving the object {r[0]:g}-{r[1]:g} m (trained: up to {FULL_TASK[f'{k}_range'][1]:g})",
            (_kind(k, **{f"{k}_range": r}),),
        )
        for k, r in far.items()
    ]
    suites += [
        Suite(
            "train_nudge",
            f"nudge up to {FULL_TASK['nudge_max']:g} m before the grasp (as in training)",
            ({"nudge_max": FULL_TASK["nudge_max"]},),
        ),
        Suite(
            "heldout_far_nudge", "nudge up to 0.06 m before the grasp (twice the trained size)", ({"nudge_max": 0.06},)
        ),
    ]
    suites += [
        Suite(
            f"heldout_double_{k}",
            f"{k} twice in every episode (trained: at most once)",
            (_kind(k, **{f"{k}_max_events": 2}),),
        )
        for k in KINDS
    ]
    suites += [
        Suite("train_latency", "observations 0 or 1 step old, fixed per episode (as in training)", (_TRAIN_LATENCY,)),
        Suite(
            "heldout_latency_2",
            "observations 2 steps old (one beyond the trained maximum)",
            ({**_TRAIN_LATENCY, "obs_latency": 2, "obs_latency_max": 0},),
        ),
        Suite(
            "heldout_latency_jitter",
            "observations 0-2 steps old, redrawn at half the steps (trained: fixed per episode, at most 1)",
            ({**_TRAIN_LATENCY, "obs_latency_max": 2, "obs_latency_jitter": 0.5},),
        ),
    ]
    together = {k: v for kind in KINDS for k, v in _kind(kind).items()}
    suites += [
        Suite(
            "train_mixture",
            "each of grasp miss, drop and displacement with probability 1/4 (the full preset)",
            ({k: FULL_TASK[k] for k in together},),
        ),
        Suite(
            "heldout_all_at_once",
            "a grasp miss, a drop and a displacement in every episode",
            ({**together, "keyframe_budget": 50},),
        ),
    ]
    return suites


_TRAIN_KINDS = tuple(f"train_{k}" for k in KINDS)
HELD_OUT_AXES: tuple[Axis, ...] = (
    Axis(
        "timing",
        "when the disturbance happens within its window",
        tuple(f"train_{k}" for k in _TIMED_KINDS),
        tuple(f"heldout_late_{k}" for k in _TIMED_KINDS),
    ),
    Axis(
        "magnitude",
        "how far the object is moved",
        ("train_drop", "train_displace", "train_nudge"),
        ("heldout_far_drop", "heldout_far_displace", "heldout_far_nudge"),
    ),
    Axis("count", "events of one kind per episode", _TRAIN_KINDS, tuple(f"heldout_double_{k}" for k in KINDS)),
    Axis(
        "latency", "how old the observations are", ("train_latency",), ("heldout_latency_2", "heldout_latency_jitter")
    ),
    Axis("combination", "kinds of disturbance in one episode", ("train_mixture",), ("heldout_all_at_once",)),
)


# The disturbance axes and the visual axes (``visual_suites``): every axis a verdict is given on
ALL_AXES: tuple[Axis, ...] = (*HELD_OUT_AXES, *VISUAL_AXES)

# Every suite of the held-out protocol's disturbance axes, each once, in axis order
PROTOCOL_SUITES = tuple(dict.fromkeys(n for axis in HELD_OUT_AXES for n in axis.in_distribution + axis.held_out))
# What each study evaluates (suites or sweep groups): the held-out protocol's (``heldout``) and the paper study's
# (``full``); the study's presets (``report.config.PRESETS``) give each its episodes, ``--env.task=heldout`` /
# ``paper`` runs them in stock lerobot-eval (``stock_suites.ALIASES``)
STUDY_SUITES: dict[str, tuple[str, ...]] = {
    "heldout": ("nominal", *PROTOCOL_SUITES),
    "full": ("nominal", "slack", "edge_strip", "outside_ring", "nudge", "obs_noise", "latency", "grasp_miss", "drop",
             "displace", "random_yaw", "random_place"),
}  # fmt: skip


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
