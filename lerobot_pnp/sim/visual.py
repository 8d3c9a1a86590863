"""Visual variation as distributions: what a camera sees of the scene, never what the physics does.

Each factor is a task field ``<factor>_range`` = (min, max) of its deviation from the scene as modelled; an
episode draws the deviation uniformly in the range, and its direction (a sign, an axis, a hue) at random:

* lighting: the lights' intensity scaled by ``2 ** +-d``; the key and fill lights turned about the table's centre
  by an angle; the lights tinted toward a random hue (``d`` the tint's share, 0 white .. 1 a saturated colour);
* colours: the hue of the cube, the place marker and the table top turned by ``d`` of the hue circle (0 .. 0.5);
* cameras: the front and overhead cameras moved by ``d`` metres and turned by ``d`` radians about random axes; the
  wrist camera's mount likewise by its own, smaller ranges;
* distractors: that many visual-only objects on the table (``scene_variation.place_distractors``);
* image noise: each rendered image blurred (Gaussian, std in pixels) then given Gaussian noise (std as a fraction
  of full scale), redrawn every frame.

``(0, 0)`` is the scene as modelled, the paper value of every field (a task recorded before these fields existed
saw that scene). Every number is drawn from generators spawned from the env's seeded generator at reset
(``numpy.random.Generator.spawn`` draws nothing from it), so an episode's physics, perturbations and observation
noise are those of the same seed without variation, and its visual variation is a function of the seed. Every
variate is drawn whether its factor is on or not, in a fixed order, so two tasks that differ in one factor's range
see the same draws of every other factor for the same seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lerobot_pnp.errors import ConfigError

# field -> (the largest deviation allowed, its unit as an error message states it)
FACTORS: dict[str, tuple[float, str]] = {
    "light_intensity_range": (2.0, "log2 of the intensity factor"),
    "light_direction_range": (math.pi / 2, "rad"),
    "light_color_range": (1.0, "share of a saturated tint"),
    "cube_hue_range": (0.5, "fraction of the hue circle"),
    "target_hue_range": (0.5, "fraction of the hue circle"),
    "table_hue_range": (0.5, "fraction of the hue circle"),
    "camera_shift_range": (0.1, "m"),
    "camera_tilt_range": (0.35, "rad"),
    "wrist_camera_shift_range": (0.02, "m"),
    "wrist_camera_tilt_range": (0.17, "rad"),
    "image_noise_range": (0.2, "std as a fraction of full scale"),
    "image_blur_range": (3.0, "std in pixels"),
}
MAX_DISTRACTORS = 3
COUNT_FIELD = "distractors_range"
FIELDS = (*FACTORS, COUNT_FIELD)
MOVED_CAMERAS = ("front", "overhead")  # the cameras fixed in the room; the wrist camera rides on the gripper
_N_UNIFORM = 21  # uniform variates per episode (fixed, see draw)
_N_NORMAL = 18  # normal variates per episode: a direction and an axis per camera


def validate(cfg) -> None:
    """One-line ConfigErrors naming the field, its valid range and the bad value; normalises each to a tuple."""
    for name, (limit, unit) in FACTORS.items():
        lo, hi = _pair(cfg, name, float)
        if not 0 <= lo <= hi <= limit:
            raise ConfigError(
                f"env.{name} must be (min, max) with 0 <= min <= max <= {limit:g} ({unit}), got {[lo, hi]}"
            )
        setattr(cfg, name, (lo, hi))
    lo, hi = _pair(cfg, COUNT_FIELD, int)
    if not 0 <= lo <= hi <= MAX_DISTRACTORS:
        raise ConfigError(
            f"env.{COUNT_FIELD} must be (min, max) whole numbers with 0 <= min <= max <= {MAX_DISTRACTORS}, got {[lo, hi]}"
        )
    setattr(cfg, COUNT_FIELD, (lo, hi))


def _pair(cfg, name: str, kind: type) -> tuple:
    value = getattr(cfg, name)
    what = "whole numbers" if kind is int else "finite numbers"
    try:
        pair = tuple(value)
        ok = len(pair) == 2 and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in pair
        )
        ok = ok and (kind is float or all(float(v).is_integer() for v in pair))
    except TypeError:
        ok = False
    if not ok:
        raise ConfigError(f"env.{name} must be 2 {what} (min, max), got {value!r}")
    return tuple(kind(v) for v in pair)


def is_varied(cfg) -> bool:
    """Whether any visual factor of ``cfg`` is on (else the scene is exactly as modelled, nothing is drawn)."""
    return any(getattr(cfg, name)[1] > 0 for name in FIELDS)


@dataclass(frozen=True)
class CameraOffset:
    """A camera's deviation: a translation (m, in its parent's frame) and a rotation (unit quaternion, w first,
    applied in the camera's own frame)."""

    shift: np.ndarray
    turn: np.ndarray


@dataclass(frozen=True)
class VisualSample:
    """One episode's visual variation, drawn from its ranges (``draw``)."""

    intensity: float  # factor on the lights' intensity
    light_turn: np.ndarray  # rotation matrix of the lights about the table's centre
    tint: np.ndarray  # rgb factor on the lights' colour (mean 1)
    hue_shift: dict[str, float]  # material -> hue turn (fraction of the circle, signed)
    cameras: dict[str, CameraOffset]  # camera name -> its offset
    distractors: int
    noise_std: float  # image noise std, fraction of full scale
    blur_sigma: float  # image blur std, pixels


def _scaled(cfg, name: str, u: float) -> float:
    lo, hi = getattr(cfg, name)
    return float(lo + u * (hi - lo))


def _sign(u: float) -> float:
    return 1.0 if u < 0.5 else -1.0


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else np.array([0.0, 0.0, 1.0])


def axis_angle_quat(axis: np.ndarray, angle: float) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation by ``angle`` about ``axis``."""
    a = _unit(np.asarray(axis, dtype=float))
    return np.array([math.cos(angle / 2), *(math.sin(angle / 2) * a)])


def rotation_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix of ``angle`` about ``axis``."""
    x, y, z = _unit(np.asarray(axis, dtype=float))
    c, s = math.cos(angle), math.sin(angle)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def _tint(strength: float, hue: float) -> np.ndarray:
    import colorsys

    color = np.array(colorsys.hsv_to_rgb(hue, 1.0, 1.0))
    tint = (1 - strength) * np.ones(3) + strength * color
    return tint / tint.mean()


def draw(cfg, rng: np.random.Generator) -> VisualSample:
    """The episode's variation from ``cfg``'s ranges: ``_N_UNIFORM`` uniform and ``_N_NORMAL`` normal variates,
    always all of them, in this order (a factor that is off maps its variates to no change)."""
    u = rng.random(_N_UNIFORM)
    g = rng.standard_normal(_N_NORMAL).reshape(6, 3)
    intensity = 2.0 ** (_sign(u[1]) * _scaled(cfg, "light_intensity_range", u[0]))
    azimuth = 2 * math.pi * u[3]
    light_turn = rotation_matrix(
        np.array([math.cos(azimuth), math.sin(azimuth), 0.0]), _scaled(cfg, "light_direction_range", u[2])
    )
    tint = _tint(_scaled(cfg, "light_color_range", u[4]), u[5])
    hue_shift = {
        material: _sign(u[7 + 2 * i]) * _scaled(cfg, f"{material}_hue_range", u[6 + 2 * i])
        for i, material in enumerate(("cube", "target", "table"))
    }
    cameras = {}
    for i, camera in enumerate((*MOVED_CAMERAS, "wrist")):
        prefix = "wrist_camera" if camera == "wrist" else "camera"
        shift = _unit(g[2 * i]) * _scaled(cfg, f"{prefix}_shift_range", u[12 + 2 * i])
        turn = axis_angle_quat(g[2 * i + 1], _scaled(cfg, f"{prefix}_tilt_range", u[13 + 2 * i]))
        cameras[camera] = CameraOffset(shift, turn)
    lo, hi = cfg.distractors_range
    distractors = lo + min(int(u[18] * (hi - lo + 1)), hi - lo)
    return VisualSample(
        intensity=float(intensity),
        light_turn=light_turn,
        tint=tint,
        hue_shift=hue_shift,
        cameras=cameras,
        distractors=int(distractors),
        noise_std=_scaled(cfg, "image_noise_range", u[19]),
        blur_sigma=_scaled(cfg, "image_blur_range", u[20]),
    )
