"""Distractors: objects on the table that a camera sees and the physics does not.

A scene with distractor slots is the MJCF scene plus up to ``visual.MAX_DISTRACTORS`` mocap bodies, each one geom of
another shape and colour than the cube (a yellow ball, a red can, a purple bar), added once when the env is built
(``scene_model``), and moved on the table at each reset through ``model.body_pos`` / ``body_quat`` (``show``; the
physics' reset copies them into ``data.mocap_pos`` / ``mocap_quat``).

Why they cannot change the pick and place:

* their geoms have ``contype = conaffinity = 0``: MuJoCo makes no contact with them (a body whose geoms all have
  both zero is left out of collision detection), so the arm, the fingers and the cube pass through them;
* their bodies are mocap bodies (no joint): no degree of freedom, no mass the dynamics sees; the model's
  statistics (mean inertia, which scales the solver's tolerance, extent, which sets the renderer's clipping) are
  set to those of the scene without them;
* they are placed where a camera sees them beside the pick and the place, not over them: at least ``CLEARANCE``
  from the cube, the target and the straight way between them, apart from each other, and not in the front
  camera's line of sight to the cube or the target.

A slot the episode does not use is hidden (geom group ``HIDDEN_GROUP``, which the renderer does not draw). Without
distractors (``distractors_range`` at most 0) the env loads the MJCF scene unchanged.
"""

from __future__ import annotations

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.sim.mujoco_gl import check_mujoco_gl, default_mujoco_gl

default_mujoco_gl()  # MuJoCo reads MUJOCO_GL once, when imported (as physics.py)
check_mujoco_gl()

import mujoco  # noqa: E402

HIDDEN_GROUP = 3  # MuJoCo's renderer draws geom groups 0-2 by default
# name, MuJoCo geom type, size, rgba, height of its centre above the table top
SHAPES = (
    ("distractor_ball", mujoco.mjtGeom.mjGEOM_SPHERE, (0.022, 0.0, 0.0), (0.95, 0.8, 0.1, 1.0), 0.022),
    ("distractor_can", mujoco.mjtGeom.mjGEOM_CYLINDER, (0.02, 0.03, 0.0), (0.85, 0.15, 0.15, 1.0), 0.03),
    ("distractor_bar", mujoco.mjtGeom.mjGEOM_BOX, (0.015, 0.045, 0.015), (0.55, 0.25, 0.7, 1.0), 0.015),
)
REGION_LOW, REGION_HIGH = (0.42, -0.30), (0.82, 0.65)  # m, on the table top in the cameras' view
CLEARANCE = 0.08  # m from the cube, the target and the way between them
SPACING = 0.08  # m between distractors
SIGHT_LINE = 0.07  # m: no distractor within this of the front camera's line of sight to the cube or the target
FRONT_CAMERA_XY = np.array([1.75, 0.15])  # the front camera's place in the MJCF scene
_TRIES = 200
_STATISTICS = ("meaninertia", "meanmass", "meansize", "extent", "center")


def scene_model(slots: int) -> mujoco.MjModel:
    """The MJCF scene with ``slots`` hidden, visual-only distractors, one mocap body each (none: the file as is)."""
    base = mujoco.MjModel.from_xml_path(str(robot.scene_path()))
    if slots <= 0:
        return base
    spec = mujoco.MjSpec.from_file(str(robot.scene_path()))
    for name, kind, size, rgba, _ in SHAPES[:slots]:
        body = spec.worldbody.add_body(name=name, mocap=True)
        body.add_geom(
            name=name, type=kind, size=size, rgba=rgba, contype=0, conaffinity=0, group=HIDDEN_GROUP, mass=0.0
        )
    model = spec.compile()
    for name in _STATISTICS:  # the scene's own statistics: the solver and the renderer see the same numbers
        setattr(model.stat, name, getattr(base.stat, name))
    return model


def slot_ids(model: mujoco.MjModel, slots: int) -> list[tuple[int, int]]:
    """(body id, geom id) of each distractor slot."""
    return [(model.body(name).id, model.geom(name).id) for name, *_ in SHAPES[:slots]]


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = float(np.clip((p - a) @ ab / max(ab @ ab, 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def _clear(xy: np.ndarray, object_xy: np.ndarray, place_xy: np.ndarray, taken: list[np.ndarray]) -> bool:
    if _segment_distance(xy, object_xy, place_xy) < CLEARANCE:
        return False
    if any(np.linalg.norm(xy - other) < SPACING for other in taken):
        return False
    # nothing between the front camera and the cube or the target
    return all(_segment_distance(xy, p, FRONT_CAMERA_XY) >= SIGHT_LINE for p in (object_xy, place_xy))


def place(rng: np.random.Generator, count: int, object_xy, place_xy) -> list[np.ndarray | None]:
    """Table xy of ``count`` distractors (rejection sampling in the region; None for one no draw placed)."""
    object_xy, place_xy = np.asarray(object_xy, float)[:2], np.asarray(place_xy, float)[:2]
    taken: list[np.ndarray] = []
    out: list[np.ndarray | None] = []
    for _ in range(count):
        found = None
        for _ in range(_TRIES):
            xy = rng.uniform(REGION_LOW, REGION_HIGH)
            if _clear(xy, object_xy, place_xy, taken):
                found = xy
                break
        if found is not None:
            taken.append(found)
        out.append(found)
    return out


def show(model: mujoco.MjModel, slots: list[tuple[int, int]], spots: list[np.ndarray | None], yaw) -> None:
    """Put the distractors at ``spots`` (resting on the table, turned by ``yaw``) and hide the slots left over."""
    for k, (body, geom) in enumerate(slots):
        spot = spots[k] if k < len(spots) else None
        model.geom_group[geom] = HIDDEN_GROUP if spot is None else 0
        if spot is not None:
            model.body_pos[body] = (spot[0], spot[1], robot.TABLE_TOP_Z + SHAPES[k][4])
            model.body_quat[body] = (np.cos(yaw[k] / 2), 0.0, 0.0, np.sin(yaw[k] / 2))
