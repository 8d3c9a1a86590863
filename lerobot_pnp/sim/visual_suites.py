"""The visual axes of the held-out protocol: what a camera sees, trained within ranges and evaluated beyond them.

The training condition (``train_visual``) is every visual factor drawn from its training range
(``presets.VISUAL_TRAINING``: a few millimetres and degrees, slight tints and hue shifts, at most one distractor,
faint sensor noise). Each ``heldout_*`` suite of a visual axis is that condition with one factor drawn from its
held-out range (``HELD_OUT_RANGES``), which starts at or beyond the end of the training range, so no held-out
episode's deviation is one a training episode could have drawn. Every visual suite states every visual field, so it
means the same on top of any training task (the physics, the disturbances and the observation faults are the
training task's own, and for one seed exactly those of ``nominal``).

A policy that sees no pixels (the expert, the state planners) meets the same episodes on every visual suite: the
control that shows these axes touch only perception.
"""

from __future__ import annotations

from typing import Any

from lerobot_pnp.presets import VISUAL_TRAINING
from lerobot_pnp.sim.suite_types import Axis, Suite

# field -> its held-out range (beyond the training range of presets.VISUAL_TRAINING)
HELD_OUT_RANGES: dict[str, tuple[float, float]] = {
    "light_intensity_range": (0.8, 1.2),  # intensity x 0.44 .. 0.57 or x 1.74 .. 2.3
    "light_direction_range": (0.6, 1.0),  # 34 .. 57 degrees
    "light_color_range": (0.35, 0.6),
    "cube_hue_range": (0.25, 0.5),  # 90 .. 180 degrees of hue: hues never trained on
    "target_hue_range": (0.25, 0.5),
    "table_hue_range": (0.25, 0.5),
    "camera_shift_range": (0.02, 0.04),  # 2 .. 4 cm
    "camera_tilt_range": (0.07, 0.12),  # 4 .. 7 degrees
    "wrist_camera_shift_range": (0.005, 0.01),  # 5 .. 10 mm
    "wrist_camera_tilt_range": (0.035, 0.07),  # 2 .. 4 degrees
    "distractors_range": (2, 3),
    "image_noise_range": (0.04, 0.08),  # std 4 .. 8 % of full scale
    "image_blur_range": (1.0, 2.0),  # std 1 .. 2 pixels
}

# held-out suite -> (what it is, the fields it takes to their held-out range)
_HELD_OUT: dict[str, tuple[str, tuple[str, ...]]] = {
    "heldout_light_intensity": ("lights dimmed to about half or brightened to about twice", ("light_intensity_range",)),
    "heldout_light_direction": ("lights turned 34-57 degrees about the table", ("light_direction_range",)),
    "heldout_light_color": ("lights strongly tinted toward a random hue", ("light_color_range",)),
    "heldout_cube_color": ("the cube in a hue 90-180 degrees from its own", ("cube_hue_range",)),
    "heldout_target_color": ("the place marker in a hue 90-180 degrees from its own", ("target_hue_range",)),
    "heldout_table_color": ("the table top in a hue 90-180 degrees from its own", ("table_hue_range",)),
    "heldout_camera_shift": ("front and overhead cameras moved 2-4 cm", ("camera_shift_range",)),
    "heldout_camera_tilt": ("front and overhead cameras turned 4-7 degrees", ("camera_tilt_range",)),
    "heldout_wrist_camera": (
        "the wrist camera's mount moved 5-10 mm and turned 2-4 degrees",
        ("wrist_camera_shift_range", "wrist_camera_tilt_range"),
    ),
    "heldout_more_distractors": ("two or three distractors on the table", ("distractors_range",)),
    "heldout_image_noise": ("Gaussian image noise of std 4-8 % of full scale", ("image_noise_range",)),
    "heldout_image_blur": ("Gaussian image blur of std 1-2 pixels", ("image_blur_range",)),
}

TRAIN_SUITE = "train_visual"


def _with_held_out(fields: tuple[str, ...]) -> dict[str, Any]:
    return {**VISUAL_TRAINING, **{f: HELD_OUT_RANGES[f] for f in fields}}


def visual_suites() -> list[Suite]:
    """``train_visual`` and every held-out visual suite."""
    train = Suite(TRAIN_SUITE, "every visual factor within its training range", (dict(VISUAL_TRAINING),))
    held = [Suite(name, f"{desc} (the rest as in training)", (_with_held_out(fields),))
            for name, (desc, fields) in _HELD_OUT.items()]  # fmt: skip
    return [train, *held]


def _axis(name: str, description: str, suites: tuple[str, ...]) -> Axis:
    return Axis(name, description, (TRAIN_SUITE,), suites)


VISUAL_AXES: tuple[Axis, ...] = (
    _axis("lighting", "the lights' intensity, direction and colour",
          ("heldout_light_intensity", "heldout_light_direction", "heldout_light_color")),
    _axis("color", "the colours of the cube, the place marker and the table",
          ("heldout_cube_color", "heldout_target_color", "heldout_table_color")),
    _axis("camera", "where the cameras are and where they look",
          ("heldout_camera_shift", "heldout_camera_tilt", "heldout_wrist_camera")),
    _axis("distractors", "other objects on the table", ("heldout_more_distractors",)),
    _axis("sensor", "the camera sensor's noise and blur", ("heldout_image_noise", "heldout_image_blur")),
)  # fmt: skip
VISUAL_SUITES = (TRAIN_SUITE, *(n for a in VISUAL_AXES for n in a.held_out))
