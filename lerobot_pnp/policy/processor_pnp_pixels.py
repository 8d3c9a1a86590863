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
from lerobot.processor import PolicyAction, PolicyProcessorPipeline

from .configuration_pnp_pixels import PnpPixelsConfig
from .processor_pnp_lstm import make_pipelines


def make_pnp_pixels_pre_post_processors(
    config: PnpPixelsConfig,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None = None,
) -> tuple[
    PolicyProcessorPipeline[dict[str, Any], dict[str, Any]],
    PolicyProcessorPipeline[PolicyAction, PolicyAction],
]:
    """Build the (pre-processor, post-processor) pair; ``dataset_stats`` are the dataset's ``meta.stats``."""
    return make_pipelines(config, dataset_stats, checked=(FeatureType.STATE, FeatureType.VISUAL))
