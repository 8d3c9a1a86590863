"""Pre/post-processors of ``pnp_lookup_table``: identity on the values (it works in raw units).

LeRobot's default steps without the normaliser: the empty renaming and the device steps that stock ``lerobot-eval``
overrides by name (``rename_observations_processor``, ``device_processor``), and the batch dimension.
"""

from __future__ import annotations

from typing import Any

import torch
from lerobot.processor import PolicyAction, PolicyProcessorPipeline
from lerobot.processor.factory import make_default_policy_processor_steps, make_policy_processor_pipelines

from .configuration_pnp_lookup_table import PnpLookupTableConfig


def make_pnp_lookup_table_pre_post_processors(
    config: PnpLookupTableConfig,
    dataset_stats: dict[str, dict[str, torch.Tensor]] | None = None,
) -> tuple[
    PolicyProcessorPipeline[dict[str, Any], dict[str, Any]],
    PolicyProcessorPipeline[PolicyAction, PolicyAction],
]:
    """The (pre-processor, post-processor) pair; ``dataset_stats`` are not used (nothing is normalised)."""
    s = make_default_policy_processor_steps(config, None)
    return make_policy_processor_pipelines(
        input_steps=[s.rename_observations, s.add_batch_dim, s.to_device], output_steps=[s.to_cpu]
    )
