"""Every stock ``lerobot-train`` checkpoint of a run on our task records that task, whatever the policy.

``pnp_lstm`` writes ``pretrained_model/baxter_pnp_env.json`` in its own ``_save_pretrained``. Another policy
(ACT, Diffusion) trained on one of our datasets has no such hook, and LeRobot offers plugins none: without the
file, ``lerobot-eval`` of the checkpoint falls back to the dataset root's *current* task, which a regenerated
dataset silently changes. So, inside a ``lerobot-train`` process only, the plugin wraps that script's
``save_checkpoint``: after LeRobot's own save it records the training dataset's task (validated), or, for a
dataset that records none, the run's ``baxter_pnp`` env config. A file the policy wrote itself is kept.
"""

from __future__ import annotations

import functools
import sys
from pathlib import Path

TRAIN_MODULE = "lerobot.scripts.lerobot_train"


def install_stock_checkpoint_hook() -> bool:
    """Wrap ``lerobot-train``'s ``save_checkpoint`` when this process runs it; True when the hook is in place."""
    module = sys.modules.get(TRAIN_MODULE)
    original = getattr(module, "save_checkpoint", None)
    if original is None:
        return False
    if getattr(original, "records_pnp_task", False):
        return True

    @functools.wraps(original)
    def save_checkpoint(checkpoint_dir, step, cfg, *args, **kwargs):
        original(checkpoint_dir, step, cfg, *args, **kwargs)
        record_task(Path(checkpoint_dir), cfg)

    save_checkpoint.records_pnp_task = True
    module.save_checkpoint = save_checkpoint
    return True


def record_task(checkpoint_dir: Path, cfg) -> Path | None:
    """Write the task of training run ``cfg`` into ``checkpoint_dir/pretrained_model`` (None: not our task)."""
    from lerobot.utils.constants import PRETRAINED_MODEL_DIR

    from lerobot_pnp.integration.recorded_task import CHECKPOINT_RECORDED_FILE, dataset_task, write_checkpoint_task
    from lerobot_pnp.presets import ENV_TYPE

    directory = checkpoint_dir / PRETRAINED_MODEL_DIR
    if not directory.is_dir() or (directory / CHECKPOINT_RECORDED_FILE).is_file():
        return None
    root = dataset_root(cfg)
    task = dataset_task(root) if root is not None else None
    env = getattr(cfg, "env", None)
    if task is None and getattr(env, "type", None) == ENV_TYPE:
        task = {"type": ENV_TYPE, **env.to_dict()}
    return None if task is None else write_checkpoint_task(task, directory)


def dataset_root(cfg) -> Path | None:
    """The local folder of training run ``cfg``'s dataset (``--dataset.root``, else LeRobot's cache folder of its
    repo id), None without a dataset."""
    from lerobot.utils.constants import HF_LEROBOT_HOME

    dataset = getattr(cfg, "dataset", None)
    root = getattr(dataset, "root", None)
    if root:
        return Path(root)
    repo_id = getattr(dataset, "repo_id", None)
    return HF_LEROBOT_HOME / repo_id if isinstance(repo_id, str) and repo_id else None


def run_config_is_ours(cfg) -> bool:
    """Whether training run ``cfg`` trains our policy, evaluates in our env, or reads a dataset that records our
    task (what the hooks check before they act)."""
    from lerobot_pnp.integration.recorded_task import RECORDED_FILE
    from lerobot_pnp.integration.stock_cli import POLICY_TYPES
    from lerobot_pnp.presets import ENV_TYPE

    if getattr(getattr(cfg, "policy", None), "type", None) in POLICY_TYPES:
        return True
    if getattr(getattr(cfg, "env", None), "type", None) == ENV_TYPE:
        return True
    root = dataset_root(cfg)
    return root is not None and (root / RECORDED_FILE).is_file()
