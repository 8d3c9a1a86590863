"""What one evaluation episode ended with (``EpisodeRecord``), its counts for a table and its JSON form.

Every evaluator writes these records (the study's stock ``eval_policy`` run through ``EpisodeRecorder``, the
expert's loop, the serial evaluator), so failures break down by cause and phase the same way everywhere.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from lerobot_pnp import robot


@dataclass
class EpisodeRecord:
    """What one evaluation episode ended with (one line of the per-episode table)."""

    seed: int
    success: bool
    failure_cause: str  # "" on success (task.FAILURE_CAUSES, or the expert's cause)
    furthest_phase: int  # index into robot.PHASE_NAMES; -1 if unknown
    perturbations: str  # comma-separated names of the perturbations that fired
    steps: int
    object_x: float  # true start position of the object (m, base frame)
    object_y: float

    @classmethod
    def from_info(cls, seed: int, info: dict, steps: int, xy) -> EpisodeRecord:
        """The record of an episode whose last env step returned ``info`` (the one mapping from an env's final
        ``info``: an episode that ended without success and without a cause was cut off, ``"truncated"``)."""
        success = bool(info.get("is_success", False))
        return cls(
            seed=seed,
            success=success,
            failure_cause="" if success else (info.get("failure_cause") or "truncated"),
            furthest_phase=int(info.get("furthest_phase", -1)),
            perturbations=str(info.get("perturbations", "")),
            steps=steps,
            object_x=float(xy[0]),
            object_y=float(xy[1]),
        )


def summarize(records: list[EpisodeRecord]) -> dict:
    """Counts for a table: successes, failures by cause and by furthest phase."""
    fails = [r for r in records if not r.success]
    by_cause: dict[str, int] = {}
    by_phase: dict[str, int] = {}
    for r in fails:
        by_cause[r.failure_cause] = by_cause.get(r.failure_cause, 0) + 1
        name = robot.phase_name(r.furthest_phase)
        by_phase[name] = by_phase.get(name, 0) + 1
    return {"n": len(records), "successes": len(records) - len(fails), "by_cause": by_cause, "by_phase": by_phase}


def records_to_json(records: list[EpisodeRecord], wall_s: float) -> dict:
    return {"wall_s": wall_s, "episodes": [asdict(r) for r in records]}


def records_from_json(data: dict) -> list[EpisodeRecord]:
    return [EpisodeRecord(**e) for e in data["episodes"]]
