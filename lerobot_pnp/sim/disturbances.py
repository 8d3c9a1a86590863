"""Perturbations as distributions: when each one fires, how large it is, how many per episode; the latency.

``Disturbances`` is the part of ``task.PickPlaceTask`` that disturbs an episode. It reads the env config's
perturbation fields (one family per kind: ``<kind>_prob``, ``<kind>_window``, ``<kind>_range``,
``<kind>_max_events``, see ``presets.PAPER_TASK``) and draws every number from the env's generator in a fixed
order, drawing none for a feature that is off.

Timing. Each event gets a time ``at`` in [0, 1] within its window, drawn uniformly at reset:

* ``at == 0`` is the original trigger, checked at the end of an env step (a grasp miss when the open gripper is
  down at the object, a drop after the step that lifted it 8 cm, a displacement when it was placed and released);
* ``at > 0`` is checked after every control tick (100 Hz inside a keyframe move, once per dense period), so the
  event can happen in the middle of a move: a grasp miss becomes a slip once the object is lifted ``at`` of the
  hover height, a drop happens once the object has travelled ``at`` of the way from where it was picked to the
  target (up to the place descent), a displacement once the released gripper has risen ``at`` of the way up.

Magnitude: each event moves the object by a distance drawn from ``<kind>_range``, in a direction spread around
the original one (``<kind>_spread``), redrawn until it lands in the ``landing_low/high`` box (where the arm can
re-pick it) and off the place target. Count: ``<kind>_max_events`` chances, each taken with ``<kind>_prob``.
"""

from __future__ import annotations

import numpy as np

from lerobot_pnp.errors import ConfigError

KINDS = ("grasp_miss", "drop", "displace")
_LANDING_TRIES = 100  # redraws of a direction and distance that lands outside the landing box
_LIFTED = 0.02  # m above its resting height: the object counts as lifted (a drop in the middle of a move)
_LEGACY_DROP_LIFT = 0.08  # m: the original drop trigger (after the step that lifted the object this far)


class Disturbances:
    """The episode's perturbation schedule and the code that applies it to the physics."""

    def __init__(self, config):
        self.config = config
        self.pending: dict[str, list[float]] = {k: [] for k in KINDS}
        self.fired: list[str] = []
        self.latency = config.obs_latency
        self.nudge_step = config.nudge_at_step
        self._pick_xy: np.ndarray | None = None
        self._settle = False
        self._rng: np.random.Generator | None = None
        self._task = None

    # ------------------------------------------------------------------ schedule
    def reset(self, rng: np.random.Generator, draw_bias) -> None:
        """Draw the episode's events: counts (the original order), ``draw_bias()``, then times, nudge step,
        latency. Nothing is drawn for a feature that is off."""
        c = self.config
        counts = {
            k: sum(_bernoulli(rng, getattr(c, f"{k}_prob")) for _ in range(getattr(c, f"{k}_max_events")))
            for k in KINDS
        }
        draw_bias()
        self.pending = {
            k: sorted(_uniform(rng, *getattr(c, f"{k}_window")) for _ in range(n)) for k, n in counts.items()
        }
        self.nudge_step = c.nudge_at_step
        if c.nudge_max > 0 and c.nudge_last_step > c.nudge_at_step:
            self.nudge_step = int(rng.integers(c.nudge_at_step, c.nudge_last_step + 1))
        self.latency = c.obs_latency
        if c.obs_latency_max > c.obs_latency:
            self.latency = int(rng.integers(c.obs_latency, c.obs_latency_max + 1))
        self.fired, self._pick_xy, self._settle, self._rng = [], None, False, rng

    def attach(self, task, physics) -> None:
        """Check mid-move events after every control tick while any is pending (else no per-tick cost)."""
        self._task = task
        mid_move = any(at > 0 for times in self.pending.values() for at in times[:1])
        physics.disturb = self._on_tick if mid_move else None

    def observed_latency(self, rng: np.random.Generator) -> int:
        """This step's latency: the episode's, redrawn within the range with probability ``obs_latency_jitter``."""
        c = self.config
        if c.obs_latency_jitter > 0 and c.obs_latency_max > c.obs_latency and rng.uniform() < c.obs_latency_jitter:
            self.latency = int(rng.integers(c.obs_latency, c.obs_latency_max + 1))
        return self.latency

    # ------------------------------------------------------------------ applying them
    def after_step(self, task, physics, step_count: int, rng: np.random.Generator) -> None:
        """End of an env step: the nudge, the original (``at == 0``) triggers, and a mid-move event that is due
        but found no moment in the move (a displacement before the episode ends on success)."""
        c = self.config
        physics.disturb = None  # nothing fires while the object falls or the nudge is applied
        if self._settle:  # a mid-move drop or slip: the object falls and comes to rest on the table
            physics.wait(0.8)
            self._settle = False
        if c.nudge_max > 0 and step_count == self.nudge_step and not physics.object_in_grasp():
            angle = rng.uniform(0, 2 * np.pi)
            radius = c.nudge_max * np.sqrt(rng.uniform())
            physics.displace_object(np.array([radius * np.cos(angle), radius * np.sin(angle), 0.0]))
            self.fired.append("nudge")
        if any(self.pending.values()):
            self._check(task, physics, rng, at_step_end=True)
        self.attach(task, physics)

    def _on_tick(self, physics) -> None:
        if self._check(self._task, physics, self._rng, at_step_end=False) in ("drop", "grasp_miss"):
            self._settle = True
            physics.disturb = None  # one event per move; the next is armed at the end of the step

    def _check(self, task, physics, rng, at_step_end: bool) -> str | None:
        """Fire the first due event (at most one per call); returns its kind."""
        c = self.config
        obj, _ = physics.object_pose()
        lift = obj[2] - physics.object_rest_z()
        due = {k: times[0] for k, times in self.pending.items() if times and ((times[0] == 0) == at_step_end)}
        if at_step_end and self.pending["displace"]:  # the last moment before the episode ends on success
            due["displace"] = self.pending["displace"][0]
        # the grasp (a contact query) only where a check reads it: where the object was picked is tracked for
        # a pending drop, and an event that no longer pends never pends again
        held = bool(self.pending["drop"] or "grasp_miss" in due) and physics.object_in_grasp()
        if held and self._pick_xy is None:
            self._pick_xy = obj[:2].copy()
        elif not held and lift < _LIFTED:
            self._pick_xy = None
        if "grasp_miss" in due:
            ee, rot = physics.ee_pose()  # only where an event may fire: this check runs after every control tick
            if due["grasp_miss"] == 0:
                near = np.linalg.norm(ee[:2] - obj[:2]) < 0.02
                hit = (
                    near
                    and physics.gripper_opening() > 0.5
                    and physics.pad_bottom_z() < obj[2] + physics.object_size / 2
                )
                hit = hit and not held
            else:
                hit = held and lift >= due["grasp_miss"] * (c.hover_height - _LIFTED)
            if hit:
                return self._fire(task, physics, rng, "grasp_miss", rot[:, 0], c.grasp_miss_range, 0.0, at_step_end)
        if "drop" in due and held:
            if due["drop"] == 0:
                hit = obj[2] > physics.object_rest_z() + _LEGACY_DROP_LIFT
            else:
                hit = lift >= _LIFTED and self._transported(task, obj) >= due["drop"]
            if hit:
                rot = physics.ee_pose()[1]
                kind = self._fire(task, physics, rng, "drop", rot[:, 0], c.drop_range, c.drop_spread, at_step_end)
                if at_step_end:
                    physics.wait(0.8)  # it falls and comes to rest on the table
                return kind
        if "displace" in due:
            rise = physics.pad_bottom_z() - (obj[2] + physics.object_size / 2)
            # the success query last: mid-move, the gripper has not risen far enough on most ticks
            if (at_step_end or rise >= due["displace"] * c.hover_height / 2) and task.is_success(physics):
                return self._fire(task, physics, rng, "displace", None, c.displace_range, c.displace_spread, True)
        return None

    def _transported(self, task, obj) -> float:
        """Fraction of the xy way from where the object was picked to the target (1 within the tolerance)."""
        dist = np.linalg.norm(obj[:2] - task.place_xy)
        if self._pick_xy is None or dist <= self.config.success_xy_tol:
            return 1.0
        start = max(np.linalg.norm(self._pick_xy - task.place_xy), 1e-6)
        return float(np.clip(1 - dist / start, 0.0, 1.0))

    def _fire(self, task, physics, rng, kind: str, gripper_x, distance_range, spread: float, in_place: bool) -> str:
        """Move the object: along the gripper's x axis (out of the fingers) or toward the object box, turned by
        up to ``spread``, by a distance from ``distance_range``; redrawn until it lands where it may.

        ``in_place``: at its height (the original perturbations: a knocked object then falls); otherwise onto the
        table (mid-move, the arm keeps moving and would bat a falling object out of the landing box)."""
        c = self.config
        obj, _ = physics.object_pose()
        toward = _toward_box(c, obj)
        if gripper_x is None:
            axis = toward
        else:
            axis = np.array([gripper_x[0], gripper_x[1]])
            axis /= max(np.linalg.norm(axis), 1e-9)
            if axis @ toward < 0:
                axis = -axis
        for _ in range(_LANDING_TRIES):
            angle = rng.uniform(-spread, spread) if spread > 0 else 0.0
            direction = np.array(
                [axis[0] * np.cos(angle) - axis[1] * np.sin(angle), axis[0] * np.sin(angle) + axis[1] * np.cos(angle)]
            )
            offset = direction * rng.uniform(*distance_range)
            if self._may_land(task, obj[:2] + offset):
                break
        else:  # no draw landed inside the box: the nearest point of the box (the distance is then shorter)
            lo, hi = np.asarray(c.landing_low), np.asarray(c.landing_high)
            offset = np.clip(obj[:2] + offset, lo, hi) - obj[:2]
        drop_z = 0.0 if in_place else min(0.0, physics.object_rest_z() + 0.002 - obj[2])
        physics.displace_object(np.array([offset[0], offset[1], drop_z]))
        self.pending[kind].pop(0)
        self.fired.append(kind)
        return kind

    def _may_land(self, task, xy: np.ndarray) -> bool:
        c = self.config
        lo, hi = np.asarray(c.landing_low), np.asarray(c.landing_high)
        if np.all(lo == hi):  # no landing box: anywhere (the original perturbations)
            return True
        inside = bool(np.all((lo <= xy) & (xy <= hi)))
        return inside and np.linalg.norm(xy - task.place_xy) > c.success_xy_tol + 0.06


def _toward_box(c, obj: np.ndarray) -> np.ndarray:
    centre = (np.asarray(c.object_low) + np.asarray(c.object_high)) / 2
    d = centre - obj[:2]
    n = np.linalg.norm(d)
    return d / n if n > 1e-6 else np.array([1.0, 0.0])


def _uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(rng.uniform(low, high)) if high > low else float(low)


def _bernoulli(rng: np.random.Generator, p: float) -> bool:
    """True with probability ``p``; no draw for p = 0 or 1."""
    if p <= 0:
        return False
    return True if p >= 1 else bool(rng.uniform() < p)


# ---------------------------------------------------------------------------------------------- validation
WINDOWS = tuple(f"{k}_window" for k in KINDS)
DISTANCE_LIMITS = {"grasp_miss_range": (0.05, 0.10), "drop_range": (0.07, 0.30), "displace_range": (0.0, 0.30)}
SPREADS = ("drop_spread", "displace_spread")
COUNTS = (*(f"{k}_max_events" for k in KINDS),)


def validate(c) -> None:
    """One-line ConfigErrors naming the field and its valid range (called by the env config)."""
    for name in (*WINDOWS, *DISTANCE_LIMITS, "landing_low", "landing_high"):
        value = getattr(c, name)
        try:
            value = tuple(float(v) for v in value)
        except (TypeError, ValueError):
            raise ConfigError(f"env.{name} must be 2 numbers, got {value!r}") from None
        if len(value) != 2 or not all(np.isfinite(value)):
            raise ConfigError(f"env.{name} must be 2 finite numbers, got {list(value)}")
        setattr(c, name, value)
    for name in WINDOWS:
        lo, hi = getattr(c, name)
        if not 0 <= lo <= hi <= 1:
            raise ConfigError(
                f"env.{name} must be (first, last) fractions with 0 <= first <= last <= 1, got {[lo, hi]}"
            )
    for name, (low, high) in DISTANCE_LIMITS.items():
        lo, hi = getattr(c, name)
        if not low <= lo <= hi <= high:
            raise ConfigError(
                f"env.{name} must be (min, max) metres with {low} <= min <= max <= {high}, got {[lo, hi]}"
            )
    if any(a > b for a, b in zip(c.landing_low, c.landing_high, strict=True)):
        raise ConfigError(
            f"env.landing_low must be <= landing_high elementwise, got {list(c.landing_low)} > {list(c.landing_high)}"
        )
    for name in SPREADS:
        value = getattr(c, name)
        if not (isinstance(value, int | float) and 0 <= value <= np.pi):
            raise ConfigError(f"env.{name} must be an angle in [0, pi] rad, got {value!r}")
    if not (isinstance(c.carry_min_time, int | float) and 0 <= c.carry_min_time <= 5):
        raise ConfigError(f"env.carry_min_time must be in [0, 5] s, got {c.carry_min_time!r}")
    if not (isinstance(c.obs_latency_jitter, int | float) and 0 <= c.obs_latency_jitter <= 1):
        raise ConfigError(
            f"env.obs_latency_jitter is a probability per step and must be in [0, 1], got {c.obs_latency_jitter!r}"
        )
    for name in (*COUNTS, "nudge_last_step", "obs_latency_max"):
        value = getattr(c, name)
        if not (isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 100):
            raise ConfigError(f"env.{name} must be an integer in [0, 100], got {value!r}")
    if c.obs_latency_max and c.obs_latency_max < c.obs_latency:
        raise ConfigError(
            f"env.obs_latency_max={c.obs_latency_max} must be 0 (a fixed latency) or >= obs_latency={c.obs_latency}"
        )
