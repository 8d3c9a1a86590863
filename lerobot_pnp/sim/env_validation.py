"""What a valid ``baxter_pnp`` task is: the checks of a resolved ``BaxterPnPEnvConfig``, field group by group.

``env_config`` resolves a config (preset, recorded task, flags) and hands it here once; every check raises one
``ConfigError`` naming the field, the bad value and the allowed range. Plain Python on the config's values: no
LeRobot and no simulator (the camera names are plain data in ``presets``).
"""

from __future__ import annotations

import math
from typing import Any

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, shown
from lerobot_pnp.presets import CAMERAS, CONTROL_MODES
from lerobot_pnp.sim import disturbances, visual

KEYFRAME_FPS = robot.KEYFRAME_FPS
BOX_PAIRS = (
    ("object_low", "object_high"),
    ("object_exclude_low", "object_exclude_high"),
    ("place_low", "place_high"),
    ("start_low", "start_high"),
)
RANGES = ("yaw_range", "size_range", "mass_range", "friction_range")
MIN_IMAGE_HEIGHT, MIN_IMAGE_WIDTH, MAX_IMAGE_SIDE = 8, 32, 4096  # pixels (validate_image_size)


def validate(cfg: Any) -> None:
    """Every check of a resolved config (normalises the boxes to tuples of floats and the cameras to a list)."""
    validate_control(cfg)
    validate_boxes(cfg)
    validate_scalars(cfg)
    validate_physical(cfg)
    disturbances.validate(cfg)
    visual.validate(cfg)


def validate_control(cfg: Any) -> None:
    """Control mode, rate, episode length, cameras, image size and render effects, speed, ``lerobot-eval``'s
    task threads."""
    if cfg.control_mode not in CONTROL_MODES:
        raise ConfigError(f"env.control_mode must be one of {CONTROL_MODES}, got {shown(cfg.control_mode)}")
    cfg.cameras = list(cfg.cameras or [])
    unknown = [c for c in cfg.cameras if c not in CAMERAS]
    if unknown or len(set(cfg.cameras)) != len(cfg.cameras):
        raise ConfigError(f"env.cameras must be distinct names from {CAMERAS}, got {shown(cfg.cameras)}")
    if cfg.fps is not None and not (isinstance(cfg.fps, int) and 1 <= cfg.fps <= 500):
        raise ConfigError(f"env.fps must be an integer in [1, 500], got {cfg.fps!r}")
    if cfg.control_mode == "keyframe" and cfg.fps not in (None, KEYFRAME_FPS):
        raise ConfigError(f"env.fps: keyframe control has one step per FSM state (fps {KEYFRAME_FPS}), got {cfg.fps}")
    if cfg.episode_length is not None and not (isinstance(cfg.episode_length, int) and cfg.episode_length >= 1):
        raise ConfigError(f"env.episode_length must be an integer >= 1, got {cfg.episode_length!r}")
    validate_image_size(cfg.image_height, cfg.image_width)
    if getattr(cfg, "max_parallel_tasks", 1) > 1:
        raise ConfigError(
            f"env.max_parallel_tasks={cfg.max_parallel_tasks}: lerobot-eval would run the tasks in threads, but "
            "MuJoCo's rendering context belongs to the thread that made it, and the threads would share one policy "
            "(a recurrent policy's memory would mix their episodes); leave it at 1"
        )
    if not isinstance(cfg.render_effects, bool):
        raise ConfigError(f"env.render_effects must be true or false, got {cfg.render_effects!r}")
    if not 0 < cfg.speed <= 1:
        raise ConfigError(f"env.speed (fraction of Baxter's joint velocity limits) must be in (0, 1], got {cfg.speed}")


def validate_image_size(height: Any, width: Any) -> None:
    """The rendered image's size: what a dataset's video encoder accepts (LeRobot's SVT-AV1 crashes the writing
    process on a frame narrower than 25 pixels), up to ``MAX_IMAGE_SIDE`` (the renderer's framebuffer is the
    image's size)."""
    ok = all(
        isinstance(v, int) and not isinstance(v, bool) and low <= v <= MAX_IMAGE_SIDE
        for v, low in ((height, MIN_IMAGE_HEIGHT), (width, MIN_IMAGE_WIDTH))
    )
    if not ok:
        raise ConfigError(
            f"env.image_height must be an integer in [{MIN_IMAGE_HEIGHT}, {MAX_IMAGE_SIDE}] and env.image_width in "
            f"[{MIN_IMAGE_WIDTH}, {MAX_IMAGE_SIDE}] (pixels), got {shown(height)}x{shown(width)}"
        )


def validate_boxes(cfg: Any) -> None:
    """The xy/xyz boxes and the ranges: their sizes, finite, low <= high; the exclusion leaves room."""
    sizes = {name: 3 if name.startswith("start_") else 2 for name in (*(n for p in BOX_PAIRS for n in p), *RANGES)}
    for name, size in sizes.items():
        value = getattr(cfg, name)
        try:
            value = tuple(float(v) for v in value)
        except (TypeError, ValueError):
            raise ConfigError(f"env.{name} must be {size} numbers, got {value!r}") from None
        if len(value) != size or not all(math.isfinite(v) for v in value):
            raise ConfigError(f"env.{name} must be {size} finite numbers, got {list(value)}")
        setattr(cfg, name, value)
    for low, high in (*BOX_PAIRS, *((r, None) for r in RANGES)):
        lo, hi = (
            (getattr(cfg, low)[:1], getattr(cfg, low)[1:]) if high is None else (getattr(cfg, low), getattr(cfg, high))
        )
        if any(a > b for a, b in zip(lo, hi, strict=True)):
            raise ConfigError(
                f"env.{low} must be <= {high or 'its upper end'} elementwise, got {list(lo)} > {list(hi)}"
            )
    if all(e <= o for e, o in zip(cfg.object_exclude_low, cfg.object_low, strict=True)) and all(
        e >= o for e, o in zip(cfg.object_exclude_high, cfg.object_high, strict=True)
    ):
        raise ConfigError(
            f"env.object_exclude_low/high {list(cfg.object_exclude_low)}..{list(cfg.object_exclude_high)} "
            f"covers the whole object box {list(cfg.object_low)}..{list(cfg.object_high)}: no position is left"
        )


def validate_scalars(cfg: Any) -> None:
    """Heights, tolerances, noise, probabilities, step counts and the observe flags."""
    for name in ("hover_height", "success_xy_tol"):
        if not (isinstance(getattr(cfg, name), int | float) and 0 < getattr(cfg, name) < 1):
            raise ConfigError(f"env.{name} must be in (0, 1) m, got {getattr(cfg, name)!r}")
    for name in ("nudge_max", "obs_noise_object", "obs_noise_joints", "obs_bias_object"):
        value = getattr(cfg, name)
        if not (isinstance(value, int | float) and 0 <= value < 1):
            raise ConfigError(f"env.{name} must be in [0, 1) (metres or radians), got {value!r}")
    for name in ("grasp_miss_prob", "drop_prob", "displace_prob"):
        value = getattr(cfg, name)
        if not (isinstance(value, int | float) and 0 <= value <= 1):
            raise ConfigError(f"env.{name} is a probability per episode and must be in [0, 1], got {value!r}")
    for name, low in (("nudge_at_step", 0), ("obs_latency", 0), ("keyframe_budget", robot.N_KEYFRAMES)):
        value = getattr(cfg, name)
        if not (isinstance(value, int) and not isinstance(value, bool) and low <= value <= 10_000):
            raise ConfigError(f"env.{name} must be an integer in [{low}, 10000], got {value!r}")
    for name in ("observe_yaw", "observe_goal", "observe_phase"):
        if not isinstance(getattr(cfg, name), bool):
            raise ConfigError(f"env.{name} must be true or false, got {getattr(cfg, name)!r}")


def validate_physical(cfg: Any) -> None:
    """What the gripper and the table allow: cube size, mass, friction, the start height."""
    if not (cfg.size_range[0] >= 0.045 and cfg.size_range[1] <= 0.06):
        raise ConfigError(
            f"env.size_range must lie in [0.045, 0.06] m (the jaw closes to 36 mm), got {list(cfg.size_range)}"
        )
    if not (cfg.mass_range[0] >= 0.05 and cfg.mass_range[1] <= 2.0):
        raise ConfigError(
            f"env.mass_range must lie in [0.05, 2.0] kg (the gripper's payload), got {list(cfg.mass_range)}"
        )
    if not (cfg.friction_range[0] >= 0.3 and cfg.friction_range[1] <= 2.0):
        raise ConfigError(f"env.friction_range must lie in [0.3, 2.0], got {list(cfg.friction_range)}")
    if cfg.start_low[2] < robot.TABLE_TOP_Z + 0.05:
        raise ConfigError(
            f"env.start_low z={cfg.start_low[2]} puts the gripper within 5 cm of the table "
            f"(table top at z={robot.TABLE_TOP_Z})"
        )
