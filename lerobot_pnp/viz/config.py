"""``lerobot-pnp viz`` flags: what to show (dataset episodes, policy rollouts) and where (viewer, file, picture)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.presets import CONTROL_MODES, OBSERVATION_DEFAULTS, TASK_FIELDS

COMMAND = "lerobot-pnp viz"  # its name in an output folder's manifest (--save, --screenshot)
ENV_CHANGE_FIELDS = (*TASK_FIELDS, *OBSERVATION_DEFAULTS)
# The study's first evaluation seed (report.run.StudyConfig.eval_seed): disjoint from the seeds a dataset's
# episodes are generated with (seed 0 + slot, retries above), so a rollout shows the policy on a new episode.
UNSEEN_SEED = 100_000


@dataclass
class PolicyRef:
    """``--policy.path`` (LeRobot's spelling) is accepted as well as ``--policy_path``."""

    path: str | None = None  # the same as --policy_path: a LeRobot checkpoint (pretrained_model folder)


@dataclass
class VizConfig:
    """``lerobot-pnp viz``: inspect dataset episodes and/or policy rollouts in Rerun.

    Without ``save`` or ``screenshot`` a Rerun viewer is spawned (needs a display); with ``save`` a ``.rrd``
    file is written (open it later with ``rerun out.rrd``); with ``screenshot`` the real viewer renders the
    recording headless into a PNG.
    """

    repo_id: str | None = None  # dataset to show (local ``root`` first, then the Hub cache)
    root: str | None = None  # dataset folder
    episode_index: int | list[int] = 0  # one index or a list, e.g. --episode_index "[0, 3]"
    save: str | None = None  # write the recording to this .rrd file instead of spawning a viewer
    screenshot: str | None = None  # write a screenshot of the viewer (headless) to this .png file
    window_size: str = "1600x1000"  # viewer size for the screenshot, WIDTHxHEIGHT (logical points)
    policy_path: str | None = None  # a LeRobot checkpoint (pretrained_model folder) to run in the env
    policy: PolicyRef = field(default_factory=PolicyRef)
    # The task rollouts run in: a dataset folder or checkpoint whose recorded task to use (default: the
    # checkpoint's own, i.e. the task of the dataset it was trained on).
    task_source: str | None = None
    control_mode: str | None = None  # env mode for rollouts (default: the recorded one, else keyframe)
    # task fields (and cameras / image size) changed for the rollouts, on top of that task, e.g.
    # '{"drop_prob": 1.0, "keyframe_budget": 20}' to watch a planner re-pick a dropped cube, '{"cameras": ["front"]}'
    env_changes: dict[str, Any] = field(default_factory=dict)
    n_episodes: int = 1  # policy rollouts, seeds seed .. seed + n_episodes - 1
    # first rollout seed; default UNSEEN_SEED, an episode the policy was not trained on (datasets use seeds 0..)
    seed: int | None = None
    compare_expert: bool = True  # run the FSM expert from each rollout's start state and log the differences
    log_hz: float = 25.0  # rate of the continuous samples (simulated time)
    device: str = "cpu"  # torch device the policy runs on for rollouts (cpu, cuda, ...)

    def __post_init__(self) -> None:
        if isinstance(self.policy, dict):
            self.policy = PolicyRef(**self.policy)
        if self.policy.path and self.policy_path and self.policy.path != self.policy_path:
            raise ConfigError(f"policy_path={self.policy_path!r} and policy.path={self.policy.path!r} disagree")
        self.policy_path = self.policy_path or self.policy.path
        self.policy.path = self.policy_path
        self.episode_index = episode_list(self.episode_index)
        if bad := sorted(set(self.env_changes) - set(ENV_CHANGE_FIELDS)):
            raise ConfigError(f"env_changes has unknown fields {bad}; valid: {sorted(ENV_CHANGE_FIELDS)}")
        if self.seed is None:
            self.seed = UNSEEN_SEED
        if self.n_episodes < 1:
            raise ConfigError(f"n_episodes must be >= 1, got {self.n_episodes}")
        if not 1 <= self.log_hz <= 500:
            raise ConfigError(f"log_hz must be in [1, 500], got {self.log_hz}")
        if self.control_mode is not None and self.control_mode not in CONTROL_MODES:
            raise ConfigError(f"control_mode must be one of {CONTROL_MODES}, got {self.control_mode!r}")
        if self.save is not None and not str(self.save).endswith(".rrd"):
            raise ConfigError(f"save must be a path ending in .rrd, got {self.save!r}")
        if self.screenshot is not None and not str(self.screenshot).lower().endswith(".png"):
            raise ConfigError(f"screenshot must be a path ending in .png, got {self.screenshot!r}")
        if not re.fullmatch(r"\d{2,5}x\d{2,5}", str(self.window_size)):
            raise ConfigError(f"window_size must look like 1600x1000, got {self.window_size!r}")

    @property
    def window(self) -> tuple[int, int]:
        w, h = (int(v) for v in self.window_size.split("x"))
        return w, h


def episode_list(value: Any) -> list[int]:
    """``3``, ``[0, 3]``, ``"0, 3"`` or ``"[0 3]"`` -> a list of episode indices (>= 0)."""
    if isinstance(value, str):
        parts = [p for p in value.strip().strip("[]").replace(",", " ").split() if p]
        try:
            value = [int(p) for p in parts]
        except ValueError:
            raise ConfigError(f"episode_index must be integers, got {value!r}") from None
    if isinstance(value, int | np.integer):
        value = [int(value)]
    value = [int(v) for v in value]
    if not value:
        raise ConfigError("episode_index is empty")
    if any(v < 0 for v in value):
        raise ConfigError(f"episode_index must be >= 0, got {value}")
    return value
