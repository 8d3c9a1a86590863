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

import tempfile
from dataclasses import dataclass
from pathlib import Path

from lerobot.processor import PolicyProcessorPipeline

from lerobot_pnp.errors import ConfigError, DatasetError
from lerobot_pnp.outputs import OutputFolder, read_record
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
    num_episodes: int | None = None  # only the first n episodes of the split (None: all)
    overwrite: bool = False  # replace the files of a lookup table this command wrote in output_dir (others stay)

    def __post_init__(self):
        if self.num_episodes is not None and not (isinstance(self.num_episodes, int) and self.num_episodes >= 1):
            raise ConfigError(f"num_episodes must be an integer >= 1 or None, got {self.num_episodes!r}")


LOOKUP_TABLE_COMMAND = "lerobot-pnp lookup-table"


def write_lookup_table(cfg: LookupTableCheckpointConfig) -> dict:
    """Build the table from ``cfg.dataset_root`` and write it to ``cfg.output_dir``; returns a summary.

    The folder goes through ``lerobot_pnp.outputs``: the checkpoint's files are written all-or-nothing beside
    whatever else the folder holds, and ``--overwrite`` replaces only the files this command recorded there."""
    from lerobot_pnp.dataset.layout import is_dataset
    from lerobot_pnp.integration.recorded_task import RECORDED_FILE, dataset_task
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
    with OutputFolder(Path(cfg.output_dir).expanduser(), LOOKUP_TABLE_COMMAND) as folder:
        _check_output(folder, cfg.overwrite)
        episodes = load_train_episodes(root, split=cfg.split, limit=cfg.num_episodes)
        source = f"{root} split {cfg.split!r}" + (f", first {cfg.num_episodes} episodes" if cfg.num_episodes else "")
        policy = LookupTablePolicy(episodes, source=source)
        files = _checkpoint_files(policy, root)
        stale = folder.entries - set(files)
        folder.write_set(files)
        for name in sorted(stale):  # a file of the previous table this one does not have
            folder.remove(name)
        out = folder.path
    return {
        "output_dir": str(out),
        "episodes": policy.config.table_episodes,
        "steps": policy.config.table_steps,
        "source": source,
        "evaluate": f"lerobot-eval --policy.path={out} --env.type=baxter_pnp --policy.device=cpu",
    }


def _checkpoint_files(policy: LookupTablePolicy, dataset_root: Path) -> dict[str, bytes]:
    """The checkpoint folder's files (name -> bytes): the policy, its identity processors, the dataset's task."""
    from lerobot_pnp.integration.recorded_task import copy_recorded

    with tempfile.TemporaryDirectory(prefix="lerobot_pnp_lookup_") as tmp:
        policy.save_pretrained(Path(tmp))
        for pipeline in identity_processors(policy.config):
            pipeline.save_pretrained(tmp)
        copy_recorded(dataset_root, tmp)
        return {p.name: p.read_bytes() for p in sorted(Path(tmp).iterdir()) if p.is_file()}


def _is_table_file(name: str) -> bool:
    """A name a lookup-table checkpoint's file has (``_checkpoint_files``)."""
    from lerobot_pnp.integration.recorded_task import CHECKPOINT_RECORDED_FILE

    return name in ("config.json", "model.safetensors", CHECKPOINT_RECORDED_FILE) or (
        name.startswith("policy_") and name.endswith((".json", ".safetensors"))
    )


def _legacy_table(folder: OutputFolder) -> list[str]:
    """The files of a lookup table written before the manifest (its ``config.json`` says ``pnp_lookup_table``,
    nothing is recorded yet); a user's file beside them is not among them."""
    config = read_record(folder.path / "config.json")
    ours = not folder.owners and isinstance(config, dict) and config.get("type") == "pnp_lookup_table"
    return [n for n in folder.foreign() if _is_table_file(n) and (folder.path / n).is_file()] if ours else []


def _check_output(folder: OutputFolder, overwrite: bool) -> None:
    """Refuse a user's entry under a name a table's checkpoint has, and a table of this command's without
    ``overwrite`` (a table from before the manifest is recorded as this command's then); other files stay."""
    legacy = _legacy_table(folder)
    ours = folder.entries | set(legacy)
    if blocking := [n for n in folder.foreign() if _is_table_file(n) and n not in ours]:
        raise ConfigError(
            f"lookup-table: {folder.path / blocking[0]} exists and `{LOOKUP_TABLE_COMMAND}` did not write it (a "
            "lookup-table checkpoint has a file of that name); move it or choose another --output_dir"
        )
    if not overwrite and any((folder.path / n).exists() or (folder.path / n).is_symlink() for n in ours):
        raise ConfigError(
            f"lookup-table: {folder.path} already holds a lookup table; pass --overwrite true to replace it"
        )
    if legacy:
        folder.adopt(*legacy)
