"""Pre/post-processors of ``pnp_lstm``: LeRobot's default pipelines.

Pre: rename (none) -> add batch dim -> device -> MEAN_STD normalisation of STATE, ENV and ACTION.
Post: unnormalise the action -> CPU. Every step is a LeRobot built-in (registered by LeRobot itself),
so the saved ``policy_preprocessor.json`` / ``policy_postprocessor.json`` load without this package.

Windowed training keys arrive as ``(B, T, D)``; the normaliser broadcasts its ``(D,)`` stats over the
leading dimensions, so windows are normalised exactly like single frames. ``<key>_is_pad`` masks pass
through untouched (complementary data).
"""

from __future__ import annotations

from typing import Any

import torch
from lerobot.processor import PolicyAction, PolicyProcessorPipeline, make_default_pre_post_processors

from .configuration_pnp_lstm import PnpLstmConfig


def make_pnp_lstm_pre_post_processors(
    config: PnpLstmConfig,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None = None,
) -> tuple[
    PolicyProcessorPipeline[dict[str, Any], dict[str, Any]],
    PolicyProcessorPipeline[PolicyAction, PolicyAction],
]:
    """Build the (pre-processor, post-processor) pair; ``dataset_stats`` are the dataset's ``meta.stats``."""
    return make_default_pre_post_processors(config, dataset_stats, normalizer_device=config.device)
