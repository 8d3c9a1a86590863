"""Pre/post-processors of ``pnp_lstm``: a batch check, then LeRobot's default pipelines.

Pre: check the batch against the checkpoint's features -> rename (none) -> add batch dim -> device ->
MEAN_STD normalisation of STATE, ENV and ACTION. Post: unnormalise the action -> CPU [-> snap the gripper
command to open or closed, with ``binary_gripper``].

The check is the one place that checks observations (the policy itself does not): every batch passes it,
the env's observations in ``lerobot-eval`` and the dataset's windows in ``lerobot-train``. Without it an env
or dataset that does not fit the checkpoint fails deep inside the normaliser with a bare tensor-size error,
and a NaN in a dataset becomes a NaN loss many steps later. It is registered on import as
``pnp_lstm_check_observation`` (importing the plugin registers it).

Windowed training keys arrive as ``(B, L, D)``; the normaliser broadcasts its ``(D,)`` stats over the
leading dimensions, so windows are normalised exactly like single frames. ``<key>_is_pad`` masks pass
through untouched (complementary data).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch
from lerobot.configs import FeatureType
from lerobot.processor import (
    ActionProcessorStep,
    ObservationProcessorStep,
    PolicyAction,
    PolicyProcessorPipeline,
    ProcessorStepRegistry,
    TransitionKey,
    make_default_policy_processor_steps,
    make_policy_processor_pipelines,
)
from lerobot.utils.constants import ACTION, OBS_PREFIX

from lerobot_pnp.errors import DatasetError, PolicyError

from .configuration_pnp_lstm import PnpLstmConfig


@ProcessorStepRegistry.register("pnp_lstm_check_observation")
@dataclass
class CheckObservationStep(ObservationProcessorStep):
    """Raise a clear error when an input is missing, has the wrong size, or is not finite.

    ``PolicyError`` for observations that do not fit the checkpoint (an env or a batch from elsewhere);
    ``DatasetError`` naming the episode and frame for a non-finite value in a dataset batch (one that carries
    ``episode_index``, as ``lerobot-train``'s do).
    """

    expected: dict[str, list[int]] = field(default_factory=dict)  # feature -> shape the checkpoint was trained on
    action_shape: list[int] | None = None  # checked when a batch carries an action (training)
    fps: int | None = None  # dataset fps and window offsets: to name the frame of a bad value
    delta_indices: list[int] | None = None
    policy: str = "pnp_lstm"  # the policy type its messages name

    def __call__(self, transition):
        transition = super().__call__(transition)
        action = transition.get(TransitionKey.ACTION)
        if isinstance(action, torch.Tensor) and self.action_shape is not None:
            extra = transition.get(TransitionKey.COMPLEMENTARY_DATA) or {}
            self._check(ACTION, action, self.action_shape, extra)
        return transition

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        extra = (self._current_transition or {}).get(TransitionKey.COMPLEMENTARY_DATA) or {}
        for key, shape in self.expected.items():
            if key not in observation:
                raise PolicyError(
                    f"{self.policy}: observation {key!r} is missing (the checkpoint needs {sorted(self.expected)}; "
                    f"got {sorted(k for k in observation if k.startswith(OBS_PREFIX))})"
                )
            self._check(key, observation[key], shape, extra)
        return observation

    def _check(self, key: str, value: Any, shape: list[int], extra: dict) -> None:
        if not isinstance(value, torch.Tensor):
            value = torch.as_tensor(value)
        if tuple(value.shape[-len(shape) :]) != tuple(shape):
            what = "observation " if key.startswith(OBS_PREFIX) else ""
            raise PolicyError(
                f"{self.policy}: {what}{key!r} has shape {tuple(value.shape)} but the checkpoint was trained on "
                f"{tuple(shape)} per frame: this checkpoint is for a different env or dataset"
            )
        if value.is_floating_point() and not bool(torch.isfinite(value).all()):
            raise self._non_finite(key, value, len(shape), extra)

    def _non_finite(self, key: str, value: torch.Tensor, feature_ndim: int, extra: dict) -> Exception:
        bad = (~torch.isfinite(value)).flatten(start_dim=value.ndim - feature_ndim).any(dim=-1)
        pad = extra.get(f"{key}_is_pad")
        if isinstance(pad, torch.Tensor) and pad.shape == bad.shape and bool((bad & ~pad.bool()).any()):
            bad = bad & ~pad.bool()  # padded positions are copies of the episode's first/last frame
        where = tuple(int(i) for i in bad.nonzero()[0]) if bad.ndim else ()
        row = where[0] if where else 0
        episodes = extra.get("episode_index")
        if episodes is None:
            return PolicyError(f"{self.policy}: observation {key!r} contains NaN or inf (batch row {row})")
        episode = int(torch.as_tensor(episodes).reshape(-1)[row])
        frame = "?"
        timestamps = extra.get("timestamp")
        if self.fps and timestamps is not None:
            frame0 = round(float(torch.as_tensor(timestamps).reshape(-1)[row]) * self.fps)
            offset = self.delta_indices[where[1]] if self.delta_indices and len(where) > 1 else 0
            frame = str(frame0 + offset)
        return DatasetError(
            f"{key} contains NaN or inf in episode {episode}, frame {frame}: fix or regenerate the dataset "
            "(lerobot-pnp generate validates what it writes)"
        )

    def get_config(self) -> dict[str, Any]:
        return {
            "expected": self.expected,
            "action_shape": self.action_shape,
            "fps": self.fps,
            "delta_indices": self.delta_indices,
        }

    def transform_features(self, features):
        return features


# The env's gripper commands (lerobot_pnp.robot; the policy package imports nothing of the simulator side).
GRIPPER_OPEN, GRIPPER_CLOSED = 1.0, 0.0


@ProcessorStepRegistry.register("pnp_lstm_binary_gripper")
@dataclass
class BinaryGripperStep(ActionProcessorStep):
    """Snap the gripper command (the last action dimension) to open or closed.

    Every demonstration commands the gripper fully open or fully closed. A regression head that is unsure
    (say 25 % of similar training states opened) outputs the mean, 0.25, and a gripper a quarter open drops
    the object; thresholding half-way turns the mean into the more likely of the two commands."""

    threshold: float = 0.5 * (GRIPPER_OPEN + GRIPPER_CLOSED)

    def action(self, action):
        out = action.clone()
        grip = out[..., -1]
        out[..., -1] = torch.where(
            grip > self.threshold,
            torch.full_like(grip, GRIPPER_OPEN),
            torch.full_like(grip, GRIPPER_CLOSED),
        )
        return out

    def get_config(self) -> dict[str, Any]:
        return {"threshold": self.threshold}

    def transform_features(self, features):
        return features


def make_pnp_lstm_pre_post_processors(
    config: PnpLstmConfig,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None = None,
) -> tuple[
    PolicyProcessorPipeline[dict[str, Any], dict[str, Any]],
    PolicyProcessorPipeline[PolicyAction, PolicyAction],
]:
    """Build the (pre-processor, post-processor) pair; ``dataset_stats`` are the dataset's ``meta.stats``."""
    return make_pipelines(config, dataset_stats, checked=(FeatureType.STATE, FeatureType.ENV))


def make_pipelines(
    config: PnpLstmConfig,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None,
    checked: tuple[FeatureType, ...],
) -> tuple[
    PolicyProcessorPipeline[dict[str, Any], dict[str, Any]],
    PolicyProcessorPipeline[PolicyAction, PolicyAction],
]:
    """The pipelines of pnp_lstm and its siblings, which differ only in the input types the observation check
    holds to the training features (``checked``): LeRobot's default steps behind that check, and the optional
    gripper snap after unnormalising."""
    s = make_default_policy_processor_steps(config, dataset_stats, normalizer_device=config.device)
    expected = {key: list(ft.shape) for key, ft in (config.input_features or {}).items() if ft.type in checked}
    action = (config.output_features or {}).get(ACTION)
    check = CheckObservationStep(
        expected=expected,
        action_shape=list(action.shape) if action is not None else None,
        fps=config.dataset_fps,
        delta_indices=config.observation_delta_indices,
        policy=config.type,
    )
    return make_policy_processor_pipelines(
        input_steps=[check, s.rename_observations, s.add_batch_dim, s.to_device, s.normalize],
        output_steps=[s.unnormalize, s.to_cpu, *([BinaryGripperStep()] if config.binary_gripper else [])],
    )
