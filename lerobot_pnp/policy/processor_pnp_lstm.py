"""Pre/post-processors of ``pnp_lstm``: a feature check, then LeRobot's default pipelines.

Pre: check observations against the checkpoint's inputs -> rename (none) -> add batch dim -> device ->
MEAN_STD normalisation of STATE, ENV and ACTION. Post: unnormalise the action -> CPU.

The check is the one custom step (registered on import as ``pnp_lstm_check_observation``; importing the
plugin registers it): without it an env or dataset whose observations do not fit the checkpoint fails deep
inside the normaliser with a bare tensor-size error; with it the error names the feature, both shapes and
NaN/inf values.

Windowed training keys arrive as ``(B, T, D)``; the normaliser broadcasts its ``(D,)`` stats over the
leading dimensions, so windows are normalised exactly like single frames. ``<key>_is_pad`` masks pass
through untouched (complementary data).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch
from lerobot.configs import FeatureType
from lerobot.processor import (
    ObservationProcessorStep,
    PolicyAction,
    PolicyProcessorPipeline,
    ProcessorStepRegistry,
    make_default_policy_processor_steps,
    make_policy_processor_pipelines,
)

from .configuration_pnp_lstm import PnpLstmConfig


@ProcessorStepRegistry.register("pnp_lstm_check_observation")
@dataclass
class CheckObservationStep(ObservationProcessorStep):
    """Raise a clear ValueError when an observation is missing, has the wrong size, or is not finite."""

    expected: dict[str, list[int]] = field(default_factory=dict)  # feature -> shape the checkpoint was trained on

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        for key, shape in self.expected.items():
            if key not in observation:
                raise ValueError(
                    f"pnp_lstm: observation {key!r} is missing (the checkpoint needs {sorted(self.expected)}; "
                    f"got {sorted(k for k in observation if k.startswith('observation.'))})"
                )
            value = observation[key]
            if not isinstance(value, torch.Tensor):
                value = torch.as_tensor(value)
            if tuple(value.shape[-len(shape) :]) != tuple(shape):
                raise ValueError(
                    f"pnp_lstm: observation {key!r} has shape {tuple(value.shape)} but the checkpoint was trained "
                    f"on {tuple(shape)} per frame: this checkpoint is for a different env or dataset"
                )
            if value.is_floating_point() and not bool(torch.isfinite(value).all()):
                raise ValueError(f"pnp_lstm: observation {key!r} contains NaN or inf: {value.tolist()}")
        return observation

    def get_config(self) -> dict[str, Any]:
        return {"expected": self.expected}

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
    s = make_default_policy_processor_steps(config, dataset_stats, normalizer_device=config.device)
    expected = {
        key: list(ft.shape)
        for key, ft in (config.input_features or {}).items()
        if ft.type in (FeatureType.STATE, FeatureType.ENV)
    }
    return make_policy_processor_pipelines(
        input_steps=[
            CheckObservationStep(expected=expected),
            s.rename_observations,
            s.add_batch_dim,
            s.to_device,
            s.normalize,
        ],
        output_steps=[s.unnormalize, s.to_cpu],
    )
