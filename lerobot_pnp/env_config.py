"""LeRobot env config ``baxter_pnp``: lets ``lerobot-eval``/``lerobot-train`` build the env (vectorised)."""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.configs import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_IMAGES, OBS_STATE

from lerobot_pnp import robot
from lerobot_pnp.env import CAMERAS, CONTROL_MODES, DEFAULT_MAX_STEPS
from lerobot_pnp.errors import ConfigError

GYM_NAMESPACE = "lerobot_pnp"
GYM_TASK = "BaxterPnP-v0"
GYM_ID = f"{GYM_NAMESPACE}/{GYM_TASK}"  # keyframe control (the paper's)
DENSE_GYM_ID = f"{GYM_NAMESPACE}/BaxterPnPDense-v0"  # dense control at DENSE_FPS
KEYFRAME_FPS = robot.KEYFRAME_FPS
DENSE_FPS = 20


@EnvConfig.register_subclass("baxter_pnp")
@dataclass
class BaxterPnPEnvConfig(EnvConfig):
    """``--env.type=baxter_pnp``. ``fps`` defaults to 1 in keyframe mode and 20 in dense mode."""

    task: str | None = GYM_TASK
    fps: int | None = None
    control_mode: str = "keyframe"
    episode_length: int | None = None  # env steps; default 10 (keyframe) / 400 (dense)
    cameras: list[str] = field(default_factory=list)
    image_height: int = 240
    image_width: int = 320
    speed: float = 1.0
    # Perturbations for robustness evaluation (see TaskConfig).
    nudge_max: float = 0.0
    nudge_at_step: int = 1
    obs_noise_object: float = 0.0
    obs_noise_joints: float = 0.0
    features: dict[str, PolicyFeature] = field(default_factory=dict)
    features_map: dict[str, str] = field(default_factory=dict)

    def __post_init__(self):
        if self.control_mode not in CONTROL_MODES:
            raise ConfigError(f"env.control_mode must be one of {CONTROL_MODES}, got {self.control_mode!r}")
        unknown = [c for c in self.cameras if c not in CAMERAS]
        if unknown:
            raise ConfigError(f"env.cameras: unknown camera(s) {unknown}; available: {CAMERAS}")
        if self.fps is None:
            self.fps = KEYFRAME_FPS if self.control_mode == "keyframe" else DENSE_FPS
        if self.episode_length is None:
            self.episode_length = DEFAULT_MAX_STEPS[self.control_mode]
        self.features = {
            ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(robot.ACTION_DIM,)),
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(robot.STATE_DIM,)),
            "environment_state": PolicyFeature(type=FeatureType.ENV, shape=(robot.OBJECT_DIM,)),
        }
        self.features_map = {
            ACTION: ACTION,
            "agent_pos": OBS_STATE,
            "environment_state": OBS_ENV_STATE,
        }
        for cam in self.cameras:
            self.features[f"pixels/{cam}"] = PolicyFeature(
                type=FeatureType.VISUAL, shape=(self.image_height, self.image_width, 3)
            )
            self.features_map[f"pixels/{cam}"] = f"{OBS_IMAGES}.{cam}"

    @property
    def package_name(self) -> str:
        return GYM_NAMESPACE

    @property
    def gym_kwargs(self) -> dict:
        return {
            "control_mode": self.control_mode,
            "fps": self.fps,
            "cameras": tuple(self.cameras),
            "image_size": (self.image_height, self.image_width),
            "speed": self.speed,
            "max_episode_steps": self.episode_length,
            "nudge_max": self.nudge_max,
            "nudge_at_step": self.nudge_at_step,
            "obs_noise_object": self.obs_noise_object,
            "obs_noise_joints": self.obs_noise_joints,
        }
