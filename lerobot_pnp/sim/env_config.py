"""The one description of the task: the LeRobot env config ``baxter_pnp``.

Every env in this project is built from a ``BaxterPnPEnvConfig`` through ``make_env`` (``lerobot-eval`` and
``lerobot-train`` through ``create_envs``: the same ``gym.make`` with ``gym_kwargs``, as is
``gym.make("lerobot_pnp/BaxterPnP-v0", **fields)``). It holds the whole task: where the object and the gripper
start, where the object goes, the perturbations, the control mode and the episode length. Every field is a flag
(``--env.<field>``) and a key of the JSON files under ``configs/``.

Task fields default to ``None``, which means "not set here". They are resolved once, in this order:

1. the named preset (``--env.preset``; ``paper`` = the paper's task; the values are in ``presets.py``),
2. unless a preset was named explicitly, the recorded task it is given (``recorded``: the env config recorded with
   a dataset folder or a checkpoint, ``task_source``),
3. fields given explicitly.

Building a config reads no file and no command line: its meaning is a function of its fields and of the record it
is given. Records are read at the edge: ``from_source`` (Python callers), and ``edge_records``, the records of the
sources a command line names, read before the command line is parsed (stock ``lerobot-train``'s
``--dataset.root`` and ``lerobot-eval``'s ``--policy.path`` by ``registration`` when the plugin loads, so a policy
trained on a dataset with a non-default task is evaluated on that task with no extra flag; ``--env.task_source``
of those and of ``lerobot-pnp`` commands likewise).

The observation setup (``cameras``, ``image_height``, ``image_width``, ``render_effects``) and the control mode
follow the same rule, so ``lerobot-eval --policy.path=...`` of a policy trained on camera images renders the same
cameras the same way.
A generated dataset records the resolved config (``recorded_files.write_recorded``).
"""

from __future__ import annotations

import logging
import os
from dataclasses import InitVar, dataclass, field, fields

from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_IMAGES, OBS_STATE

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, shown
from lerobot_pnp.presets import (
    ENV_TYPE,
    GYM_ID,
    GYM_NAMESPACE,
    GYM_TASK,
    OBSERVATION_DEFAULTS,
    OBSERVATION_UNRECORDED,
    PAPER_TASK,
    PRESETS,
    TASK_FIELDS,
)
from lerobot_pnp.sim.edge_records import EdgeRecords
from lerobot_pnp.sim.env_validation import validate
from lerobot_pnp.sim.mujoco_gl import default_mujoco_gl

MAX_EPISODE_LENGTH = 100_000  # env steps: every episode's arrays are held in memory (recorder, datasets)
KEYFRAME_FPS = robot.KEYFRAME_FPS
DENSE_FPS = 20
# Dense episodes: 1 s of control (20 steps) per keyframe of the budget, the keyframe methods' budget at the pace
# of the dense expert (benchmarks/dense_pace.py measures its steps per keyframe) with a margin of a few steps.
DENSE_SECONDS_PER_KEYFRAME = 1


def dense_episode_length(keyframe_budget: int, fps: int = DENSE_FPS) -> int:
    """Env steps of a dense episode with ``keyframe_budget`` keyframes at ``fps``: ``DENSE_SECONDS_PER_KEYFRAME``
    of control per keyframe (the default ``episode_length`` in dense control)."""
    return DENSE_SECONDS_PER_KEYFRAME * keyframe_budget * fps


@EnvConfig.register_subclass(ENV_TYPE)
@dataclass
class BaxterPnPEnvConfig(EdgeRecords, EnvConfig):
    """``--env.type=baxter_pnp``: Baxter pick-and-place, the whole task in one place (see module doc)."""

    # gymnasium id suffix (the one task), or evaluation suites, comma-separated: heldout, paper, drop,... (stock_suites)
    task: str | None = GYM_TASK
    fps: int | None = None  # keyframe: 1 (one FSM state per step); dense: control rate, default 20
    # Named task preset: "paper" (the paper's setting) or "full" (everything on). None = the recorded task, else paper
    preset: str | None = None
    # A dataset folder or checkpoint whose recorded task to use (default: from the command line, see above).
    task_source: str | None = None
    # keyframe (one step = move to a joint keyframe) | dense (one control period); None = the recorded one, else keyframe
    control_mode: str | None = None
    episode_length: int | None = None  # env steps before truncation; default keyframe_budget (dense: 1 s per keyframe)
    # ---- observation setup (None = the recorded one, else OBSERVATION_DEFAULTS): what an image policy consumes
    cameras: list[str] | None = None  # rendered camera observations: front, overhead, wrist
    image_height: int | None = None  # rendered camera image height (pixels)
    image_width: int | None = None  # rendered camera image width (pixels)
    # shadows, reflections and 4x multisampling (MuJoCo's default visuals); off renders a frame several times faster
    render_effects: bool | None = None
    speed: float = 1.0  # fraction of Baxter's joint velocity limits used by the interpolator
    straight_paths: bool = True  # keyframe moves keep the gripper on a straight line (else joint-linear)
    # ---- task (None = from the preset / recorded task; the values are in PAPER_TASK / FULL_TASK)
    object_low: tuple[float, float] | None = None  # object xy box, low corner (m, base frame; reachable gripper-down)
    object_high: tuple[float, float] | None = None  # object xy box, high corner (m)
    # low corner of an xy box where no object is placed (low == high: none); with object_low/high it makes a band
    object_exclude_low: tuple[float, float] | None = None
    object_exclude_high: tuple[float, float] | None = None  # high corner of that excluded xy box (m)
    yaw_range: tuple[float, float] | None = None  # object yaw drawn in this range (rad); the paper varies position only
    place_low: tuple[float, float] | None = None  # place target xy box, low corner (m); a point in the paper
    place_high: tuple[float, float] | None = None  # place target xy box, high corner (outside the object box)
    start_low: tuple[float, float, float] | None = None  # gripper start xyz box, low corner (m; gripper pointing down)
    start_high: tuple[float, float, float] | None = None  # gripper start xyz box, high corner (m)
    hover_height: float | None = None  # the paper's h: approach / retract height above the object (m)
    success_xy_tol: float | None = None  # the object within this xy distance of the target (m) counts as placed
    size_range: tuple[float, float] | None = None  # cube edge length (m), drawn per episode
    mass_range: tuple[float, float] | None = None  # object mass (kg), drawn per episode
    friction_range: tuple[float, float] | None = None  # object sliding friction coefficient, drawn per episode
    observe_yaw: bool | None = None  # environment_state gains (sin 4 yaw, cos 4 yaw): the cube's 90-degree symmetry
    observe_goal: bool | None = None  # environment_state gains the place target xy (the goal)
    # environment_state gains a one-hot of the task phase from the simulator state (privileged; the phase-told control)
    observe_phase: bool | None = None
    keyframe_budget: int | None = None  # keyframe steps per episode (dense: 1 s of control per keyframe)
    # ---- perturbations (each named, seeded, usable alone; see task.PickPlaceTask.after_step and disturbances.py)
    nudge_max: float | None = None  # the object is pushed by up to this (m, xy) after nudge_at_step steps, pre-grasp
    nudge_at_step: int | None = None  # the step after which the nudge happens (the first of its range)
    grasp_miss_prob: float | None = None  # per chance: the object slides out while the open gripper is at it
    drop_prob: float | None = None  # per chance: the object is knocked out of the gripper in transport
    displace_prob: float | None = None  # per chance: the object is moved after it was released on the target
    obs_noise_object: float | None = None  # Gaussian observation noise (std, m) on the object position
    obs_noise_joints: float | None = None  # Gaussian observation noise (std, rad) on the joint angles
    obs_bias_object: float | None = None  # a constant per-episode offset of this length (m, xy) on the observed object
    obs_latency: int | None = None  # observations are this many steps old (the low end with obs_latency_max)
    nudge_last_step: int | None = None  # the nudge step is uniform in nudge_at_step..this (<= nudge_at_step: fixed)
    # when a grasp miss happens: 0 = at the close; f > 0 = slips out once lifted f of the hover height
    grasp_miss_window: tuple[float, float] | None = None
    grasp_miss_range: tuple[float, float] | None = None  # how far the missed object slides out of the fingers (m)
    grasp_miss_max_events: int | None = None  # grasp-miss chances per episode, each taken with grasp_miss_prob
    # when a drop happens: 0 = after the lift step; f > 0 = after f of the way to the target
    drop_window: tuple[float, float] | None = None
    drop_range: tuple[float, float] | None = None  # a dropped object lands this far from where it left the fingers (m)
    drop_spread: float | None = None  # drop landing direction: up to this angle (rad) off the gripper axis; pi = any
    drop_max_events: int | None = None  # drop chances per episode, each taken with drop_prob
    # when a displacement happens: 0 = on release; f > 0 = once the gripper has risen f of h / 2
    displace_window: tuple[float, float] | None = None
    displace_range: tuple[float, float] | None = None  # how far a released object is pushed (m)
    displace_spread: float | None = None  # push direction: up to this angle (rad) off the way to the box; pi = any
    displace_max_events: int | None = None  # displacement chances per episode, each taken with displace_prob
    # a disturbed object lands only in this xy box (low corner; redrawn, else the nearest point); low == high: anywhere
    landing_low: tuple[float, float] | None = None
    landing_high: tuple[float, float] | None = None  # high corner of that landing xy box (m)
    obs_latency_max: int | None = None  # latency per episode uniform in obs_latency..this (0: fixed obs_latency)
    obs_latency_jitter: float | None = None  # per step, the latency is redrawn in its range with this probability
    # keyframe moves carrying the object last at least this long (s; a fast carry shakes a heavy cube loose); 0 = off
    carry_min_time: float | None = None
    # ---- visual variation (sim/visual.py; never the physics): (min, max) deviation per episode; (0, 0) = as modelled
    light_intensity_range: tuple[float, float] | None = None  # lights' intensity x 2^(+-d) (d: log2 of the factor)
    light_direction_range: tuple[float, float] | None = None  # lights turned about the table's centre by d (rad)
    light_color_range: tuple[float, float] | None = None  # lights tinted toward a random hue: d = the tint's share, 0-1
    cube_hue_range: tuple[float, float] | None = None  # the cube's hue turned by d of the hue circle (0-0.5)
    target_hue_range: tuple[float, float] | None = None  # the place marker's hue turned by d of the hue circle
    table_hue_range: tuple[float, float] | None = None  # the table top's hue turned by d of the hue circle
    camera_shift_range: tuple[float, float] | None = None  # front and overhead cameras moved by d (m), any direction
    camera_tilt_range: tuple[float, float] | None = None  # front and overhead cameras turned by d (rad), any axis
    wrist_camera_shift_range: tuple[float, float] | None = None  # the wrist camera's mount moved by d (m)
    wrist_camera_tilt_range: tuple[float, float] | None = None  # the wrist camera's mount turned by d (rad)
    distractors_range: tuple[int, int] | None = None  # visual-only objects on the table (0-3), clear of pick and place
    image_noise_range: tuple[float, float] | None = None  # Gaussian noise on camera images, std as a share of 255
    image_blur_range: tuple[float, float] | None = None  # Gaussian blur of camera images, std in pixels (before noise)
    features: dict[str, PolicyFeature] = field(default_factory=dict)
    features_map: dict[str, str] = field(default_factory=dict)
    # The recorded task to start from (a checked record, ``read_source``; {}: none); not a field nor a flag
    recorded: InitVar[dict | None] = None

    def __post_init__(self, recorded: dict | None):
        self._resolve_task(recorded)
        validate(self)
        if self.fps is None:
            self.fps = KEYFRAME_FPS if self.control_mode == "keyframe" else DENSE_FPS
        if self.episode_length is None:
            self.episode_length = (
                self.keyframe_budget
                if self.control_mode == "keyframe"
                else dense_episode_length(self.keyframe_budget, self.fps)
            )
        if self.episode_length > MAX_EPISODE_LENGTH:  # given, or derived from the budget and the rate
            raise ConfigError(
                f"env.episode_length {self.episode_length} (keyframe_budget {self.keyframe_budget}, "
                f"{self.control_mode} control, {self.fps} fps) is over the most, {MAX_EPISODE_LENGTH} steps"
            )
        self.features = {
            ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(robot.ACTION_DIM,)),
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(robot.STATE_DIM,)),
            "environment_state": PolicyFeature(type=FeatureType.ENV, shape=(len(self.environment_state_names),)),
        }
        self.features_map = {ACTION: ACTION, "agent_pos": OBS_STATE, "environment_state": OBS_ENV_STATE}
        for cam in self.cameras:
            self.features[f"pixels/{cam}"] = PolicyFeature(
                type=FeatureType.VISUAL, shape=(self.image_height, self.image_width, 3)
            )
            self.features_map[f"pixels/{cam}"] = f"{OBS_IMAGES}.{cam}"
        from lerobot_pnp.sim.stock_suites import check_task

        check_task(self)  # --env.task naming suites: every name known, every suite applicable to this task

    # ------------------------------------------------------------------ resolution and validation
    def _resolve_task(self, recorded: dict | None) -> None:
        if self.preset is not None and self.preset not in PRESETS:
            raise ConfigError(f"env.preset must be one of {sorted(PRESETS)}, got {shown(self.preset)}")
        if self.preset is not None:
            recorded = {}  # a named preset: no recorded task
        elif recorded is None:
            recorded = self._edge_record()
        if recorded:
            # A recorded task is complete for the fields that existed when it was recorded; a field added since
            # had no effect then, which is its paper value (every paper value means "feature off").
            base = {**PAPER_TASK, **{k: v for k, v in recorded.items() if k in TASK_FIELDS}}
        else:
            base = dict(PRESETS[self.preset or "paper"])
        for name in TASK_FIELDS:
            if getattr(self, name) is None:
                setattr(self, name, base[name])
        if self.preset is None:
            self.preset = recorded.get("preset", "paper")
        for name, default in OBSERVATION_DEFAULTS.items():
            if getattr(self, name) is None:
                if recorded:  # a record made before the field existed: the value it had then
                    default = recorded.get(name, OBSERVATION_UNRECORDED.get(name, default))
                setattr(self, name, default)
        self._resolve_control(recorded)
        self.task_source = None  # resolved: the config now stands on its own

    def _resolve_control(self, recorded: dict) -> None:
        """Control mode and rate: the recorded ones (the data a policy learned from), and an explicit flag that
        contradicts them is an error (a keyframe policy run at 20 Hz fails every episode, silently)."""
        rec_mode, rec_fps = recorded.get("control_mode"), recorded.get("fps")
        if self.control_mode is None:
            self.control_mode = rec_mode or "keyframe"
            if self.fps is None and rec_mode == self.control_mode:
                self.fps = rec_fps
        elif rec_mode and self.control_mode != rec_mode:
            raise ConfigError(
                f"env.control_mode={self.control_mode!r} contradicts the recorded task ({rec_mode!r}, fps {rec_fps}) "
                "of the dataset/checkpoint this run uses; drop the flag, or pass --env.preset to start from a preset"
            )
        elif rec_mode and self.fps is not None and rec_fps is not None and self.fps != rec_fps:
            raise ConfigError(f"env.fps={self.fps} contradicts the recorded fps {rec_fps} of the dataset/checkpoint")

    @property
    def environment_state_names(self) -> list[str]:
        """Names of the ``environment_state`` dimensions (``observation.environment_state`` in datasets)."""
        names = list(robot.OBJECT_NAMES)
        if self.observe_yaw:
            names += list(robot.OBJECT_YAW_NAMES)
        if self.observe_goal:
            names += list(robot.GOAL_NAMES)
        if self.observe_phase:
            names += [f"phase={name}" for name in robot.PHASE_NAMES]
        return names

    # ------------------------------------------------------------------ LeRobot EnvConfig API
    @property
    def package_name(self) -> str:
        return GYM_NAMESPACE

    def create_envs(self, n_envs: int, use_async_envs: bool = False):
        """LeRobot's vector envs (what ``lerobot-eval`` and in-training eval build), sync for keyframe control.

        ``lerobot-eval`` asks for async envs by default: one worker process per env, each importing LeRobot and
        MuJoCo (several hundred MB). A keyframe step is short, so those workers cost far more start-up time and
        memory than they save: keyframe control gets a ``SyncVectorEnv`` with a warning. Dense control keeps async
        workers while there is a CPU for each; more workers than CPUs only contend for them (a batch of 50 on a
        laptop would start 50 interpreters), so it then runs in this process too, with a warning.
        """
        # the CPUs this process may run on (a SLURM job or taskset may allow fewer than the machine has)
        cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        if use_async_envs and n_envs > 1 and (self.control_mode == "keyframe" or n_envs > cpus):
            why = "keyframe control" if self.control_mode == "keyframe" else f"dense control on {cpus} CPUs"
            logging.getLogger(__name__).warning(
                "baxter_pnp: %s runs its %d eval envs in this process (SyncVectorEnv) instead of %d async worker "
                "processes, which would only add start-up time and memory",
                why,
                n_envs,
                n_envs,
            )
            use_async_envs = False
        default_mujoco_gl()  # before this process or its env workers import MuJoCo
        from lerobot_pnp.sim.stock_suites import create_suite_envs

        suites = create_suite_envs(self, n_envs, use_async_envs)  # --env.task naming suites: one entry each
        return suites if suites is not None else super().create_envs(n_envs, use_async_envs=use_async_envs)

    @property
    def gym_kwargs(self) -> dict:
        """What ``gym.make`` receives: the resolved config as JSON values (the env truncates at ``episode_length``)."""
        return {"config": self.to_dict()}

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict:
        """The resolved config as plain JSON values (what a dataset records and an env is rebuilt from)."""
        skip = {"features", "features_map", "task_source"}
        out = {}
        for f in fields(self):
            if f.name in skip:
                continue
            value = getattr(self, f.name)
            out[f.name] = list(value) if isinstance(value, tuple | list) else value
        return out

    @classmethod
    def from_dict(cls, data: dict, **overrides) -> BaxterPnPEnvConfig:
        """Rebuild a config from ``to_dict`` output; unknown keys are an error naming the valid ones."""
        data = {k: v for k, v in {**data, **overrides}.items() if k not in ("type", "features", "features_map")}
        valid = {f.name for f in fields(cls)} - {"features", "features_map"}
        unknown = sorted(set(data) - valid)
        if unknown:
            raise ConfigError(f"unknown baxter_pnp env field(s) {unknown}; valid fields: {sorted(valid)}")
        if data.get("preset") is None and "preset" in data:
            data.pop("preset")
        if data.get("task_source"):  # its record is read here, before the config is built
            return cls.from_source(data.pop("task_source"), **data)
        return cls(**data)

    def with_changes(self, **changes) -> BaxterPnPEnvConfig:
        """A copy with some fields changed (re-validated). A derived episode length follows a changed budget,
        control mode or rate unless ``episode_length`` is among the changes."""
        if {"keyframe_budget", "control_mode", "fps"} & set(changes) and "episode_length" not in changes:
            changes = {**changes, "episode_length": None}
        if "control_mode" in changes and "fps" not in changes:
            changes = {**changes, "fps": None}  # the new mode's default rate
        return type(self).from_dict(self.to_dict(), **changes)


def make_env(config: BaxterPnPEnvConfig | dict | None = None, render_mode: str | None = "rgb_array", **changes):
    """The one factory: a gymnasium env (with the time limit) for ``config`` (default: the paper's task)."""
    import gymnasium as gym

    default_mujoco_gl()
    if config is None:
        config = BaxterPnPEnvConfig.from_dict({}, **changes)
    elif isinstance(config, dict):
        config = BaxterPnPEnvConfig.from_dict(config, **changes)
    elif changes:
        config = config.with_changes(**changes)
    return gym.make(GYM_ID, disable_env_checker=True, render_mode=render_mode, **config.gym_kwargs)
