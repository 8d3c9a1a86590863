"""The lookup table built from a dataset: the study's in-memory baseline and the checkpoint ``lerobot-eval`` loads.

One implementation, ``policy.modeling_pnp_lookup_table.PnpLookupTablePolicy`` (the open-loop nearest-neighbour
replay, a registered LeRobot policy type). The study builds it in memory from the training episodes of its dataset
(``LookupTablePolicy``, ``builders.lookup_eval``); ``lerobot-pnp lookup-table`` builds the same table from the same
episodes and writes it as a checkpoint folder, with the dataset's recorded task and identity processors, so that
``lerobot-eval --policy.path <output_dir>`` runs it like any trained checkpoint.

A command of its own rather than ``lerobot-pnp train --policy.type pnp_lookup_table``: nothing is trained (no
epochs, optimiser, seed or loss curve), and the fast trainer's config and checkpoint layout are those of a trained
run; here one dataset read and one folder.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

from lerobot.processor import PolicyProcessorPipeline

from lerobot_pnp.errors import ConfigError, DatasetError
from lerobot_pnp.policy.configuration_pnp_lookup_table import PnpLookupTableConfig
from lerobot_pnp.policy.modeling_pnp_lookup_table import PnpLookupTablePolicy, table_config
from lerobot_pnp.policy.processor_pnp_lookup_table import make_pnp_lookup_table_pre_post_processors
from lerobot_pnp.report.adapters import Episodes


class LookupTablePolicy(PnpLookupTablePolicy):
    """``PnpLookupTablePolicy`` over a dataset's ``Episodes`` (what the study and the command build)."""

    def __init__(self, episodes: Episodes, source: str = ""):
        first, actions = episodes.first_env_state, episodes.actions
        super().__init__(table_config(first, actions, source))
        self.fill(first, actions)


def identity_processors(
    config: PnpLookupTableConfig | None = None,
) -> tuple[PolicyProcessorPipeline, PolicyProcessorPipeline]:
    """Pre/post-processors of the lookup table (no normalisation): the ones its checkpoint records."""
    return make_pnp_lookup_table_pre_post_processors(config or PnpLookupTableConfig())


@dataclass
class LookupTableCheckpointConfig:
    """``lerobot-pnp lookup-table``: the lookup table over a dataset's training episodes, as a checkpoint folder."""

    dataset_root: str = ""  # the dataset folder (lerobot-pnp generate's --root)
    output_dir: str = "outputs/lookup_table"  # the checkpoint folder: lerobot-eval --policy.path <output_dir>
    split: str = "train"  # the episodes of this split of meta/info.json (all episodes if the dataset has no splits)
    n_episodes: int | None = None  # only the first n episodes of the split (None: all)
    overwrite: bool = False  # replace a lookup-table checkpoint already in output_dir (any other folder is refused)

    def __post_init__(self):
        if self.n_episodes is not None and not (isinstance(self.n_episodes, int) and self.n_episodes >= 1):
            raise ConfigError(f"n_episodes must be an integer >= 1 or None, got {self.n_episodes!r}")


def write_lookup_table(cfg: LookupTableCheckpointConfig) -> dict:
    """Build the table from ``cfg.dataset_root`` and write it to ``cfg.output_dir``; returns a summary."""
    from lerobot_pnp.dataset.layout import is_dataset
    from lerobot_pnp.recorded_task import RECORDED_FILE, copy_recorded, dataset_task
    from lerobot_pnp.report.adapters import load_train_episodes

    root = Path(cfg.dataset_root).expanduser()
    if not cfg.dataset_root or not is_dataset(root):
        raise DatasetError(
            f"lookup-table: --dataset_root {cfg.dataset_root!r} is not a dataset folder (no meta/info.json)"
        )
    if dataset_task(root) is None:
        raise DatasetError(
            f"lookup-table: {root} records no baxter_pnp task ({RECORDED_FILE}); give a dataset of lerobot-pnp generate"
        )
    out = Path(cfg.output_dir).expanduser()
    _check_output(out, cfg.overwrite)
    episodes = load_train_episodes(root, split=cfg.split, limit=cfg.n_episodes)
    source = f"{root} split {cfg.split!r}" + (f", first {cfg.n_episodes} episodes" if cfg.n_episodes else "")
    policy = LookupTablePolicy(episodes, source=source)
    if out.exists():
        shutil.rmtree(out)
    policy.save_pretrained(out)
    for pipeline in identity_processors(policy.config):
        pipeline.save_pretrained(out)
    copy_recorded(root, out)
    return {
        "output_dir": str(out),
        "episodes": policy.config.table_episodes,
        "steps": policy.config.table_steps,
        "source": source,
        "evaluate": f"lerobot-eval --policy.path={out} --env.type=baxter_pnp --policy.device=cpu",
    }


def _check_output(out: Path, overwrite: bool) -> None:
    """An absent or empty folder is written; a lookup-table checkpoint is replaced only with ``overwrite``."""
    if not out.exists() or (out.is_dir() and not any(out.iterdir())):
        return
    config = out / "config.json"
    try:
        ours = json.loads(config.read_text()).get("type") == "pnp_lookup_table"
    except (OSError, ValueError, AttributeError):
        ours = False
    if not ours:
        raise ConfigError(
            f"lookup-table: {out} exists and is not a lookup-table checkpoint; choose another --output_dir"
        )
    if not overwrite:
        raise ConfigError(f"lookup-table: {out} already holds a lookup table; pass --overwrite true to replace it")
