"""Keyframe markers in the 3D view: where a run entered each FSM phase, labelled once per *place*.

FSM phases reached at nearly the same point (grasp and close; approach, retract and the next start above the
object; descend and open) share one marker whose label names them all, and labels of nearby markers are lifted to
different heights on leader lines, so the labels do not pile up into an unreadable cluster.
"""

from __future__ import annotations

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.viz.sampling import Run, phase_name

PICK_COLOR, PLACE_COLOR = (255, 140, 0), (40, 200, 220)
MERGE_DISTANCE = 0.03  # m: keyframes closer than this share a marker and a label
LABEL_SPACING = 0.25  # m (horizontal): labels of markers closer than this are drawn on different levels
LABEL_LIFT = 0.05  # m: height of one label level above its marker


def keyframes_reached(run: Run) -> tuple[np.ndarray, list[int]]:
    """End-effector positions where the run entered each FSM phase (a recovery re-enters some), and the phase."""
    pos, phases, last = [], [], None
    for k, p in enumerate(run.frames.phase):
        if p < 0 or p == last:
            continue
        last = int(p)
        pos.append(run.samples["ee"][run.frames.sample[k]])
        phases.append(int(p))
    return np.asarray(pos).reshape(-1, 3), phases


def merged_labels(positions: np.ndarray, phases: list[int]) -> tuple[np.ndarray, list[str], list]:
    """One marker per place: phases within ``MERGE_DISTANCE`` of each other share it (see module doc).

    Labels are short: the phases' short names joined by " · " in the order reached, coloured by the subtask
    of the first (pick orange, place cyan); a place phase in a pick-coloured marker is written "place <name>".
    """
    groups: list[list[int]] = []
    for k in range(len(phases)):
        near = [g for g in groups if np.linalg.norm(positions[k] - positions[g[0]]) < MERGE_DISTANCE]
        if near:
            near[0].append(k)
        else:
            groups.append([k])
    pos, labels, colors = [], [], []
    for group in groups:
        first = _subtask(phases[group[0]])
        names = []
        for k in group:
            subtask, _, short = phase_name(phases[k]).rpartition("/")
            name = short if subtask in ("", first) else f"{subtask} {short}"
            if name not in names:
                names.append(name)
        pos.append(positions[group[0]])
        labels.append(" · ".join(names))
        colors.append(PICK_COLOR if first == robot.SUBTASKS[0] else PLACE_COLOR)
    return np.asarray(pos).reshape(-1, 3), labels, colors


def _subtask(phase: int) -> str:
    return robot.SUBTASKS[robot.Phase(min(max(int(phase), 0), len(robot.Phase) - 1)).subtask]


def label_anchors(positions: np.ndarray) -> np.ndarray:
    """Where each marker's label is drawn: above the marker, on the lowest free level.

    Markers near each other (within ``LABEL_SPACING`` horizontally) get their labels on different levels, so
    from the usual side views the texts are stacked instead of written over each other.
    """
    anchors, taken = [], []
    for p in positions:
        level = 0
        while any(lv == level and np.linalg.norm(p[:2] - q[:2]) < LABEL_SPACING for q, lv in taken):
            level += 1
        taken.append((p, level))
        anchors.append(p + [0.0, 0.0, LABEL_LIFT * (level + 1)])
    return np.asarray(anchors).reshape(-1, 3)


def log_keyframes(rec, path: str, positions: np.ndarray, phases: list[int], *, color=None, labelled=True) -> None:
    """Markers at ``path`` (their labels show on hover); with ``labelled``, the labels drawn at ``path/labels``."""
    import rerun as rr

    if len(positions) == 0:
        return
    pos, labels, colors = merged_labels(positions, phases)
    colors = [color] * len(pos) if color else colors
    rec.log(path, rr.Points3D(pos, labels=labels, colors=colors, radii=[0.012], show_labels=False), static=True)
    if not labelled:
        return
    anchors = label_anchors(pos)
    rec.log(
        f"{path}/labels",
        rr.Points3D(anchors, labels=labels, colors=colors, radii=[0.002], show_labels=True),
        static=True,
    )
    leaders = [np.stack([p, a]) for p, a in zip(pos, anchors)]
    rec.log(f"{path}/leaders", rr.LineStrips3D(leaders, colors=colors, radii=[0.0015]), static=True)
