"""Pre/post-processors of ``pnp_pixels``: ``pnp_lstm``'s pipelines, checking the joints and the images.

The check step (``pnp_lstm_check_observation``) requires the robot state and each camera's image of the trained
size, finite; not the environment state, which the policy does not need to act (a real robot has none). The
normaliser leaves images as they are (``VISUAL: IDENTITY``) and normalises the environment state where a batch
carries it (the auxiliary target in training).
"""

from __future__ import annotations

from typing import Any

import torch
from lerobot.configs import FeatureType
from lerobot.processor import (
    PolicyAction,
    PolicyProcessorPipeline,
    make_default_policy_processor_steps,
    make_policy_processor_pipelines,
)
from lerobot.utils.constants import ACTION

from .configuration_pnp_pixels import PnpPixelsConfig
from .processor_pnp_lstm import BinaryGripperStep, CheckObservationStep


def make_pnp_pixels_pre_post_processors(
    config: PnpPixelsConfig,
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
        if ft.type in (FeatureType.STATE, FeatureType.VISUAL)
    }
    action = (config.output_features or {}).get(ACTION)
    check = CheckObservationStep(
        expected=expected,
        action_shape=list(action.shape) if action is not None else None,
        fps=config.dataset_fps,
        delta_indices=config.observation_delta_indices,
    )
    return make_policy_processor_pipelines(
        input_steps=[check, s.rename_observations, s.add_batch_dim, s.to_device, s.normalize],
        output_steps=[s.unnormalize, s.to_cpu, *([BinaryGripperStep()] if config.binary_gripper else [])],
    )
