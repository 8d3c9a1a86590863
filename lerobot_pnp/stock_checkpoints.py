"""Every stock ``lerobot-train`` checkpoint records the task it was trained in, whatever the policy.

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
    from lerobot.utils.constants import HF_LEROBOT_HOME, PRETRAINED_MODEL_DIR

    from lerobot_pnp.presets import ENV_TYPE
    from lerobot_pnp.recorded_task import CHECKPOINT_RECORDED_FILE, dataset_task, write_checkpoint_task

    directory = checkpoint_dir / PRETRAINED_MODEL_DIR
    if not directory.is_dir() or (directory / CHECKPOINT_RECORDED_FILE).is_file():
        return None
    dataset = getattr(cfg, "dataset", None)
    root = getattr(dataset, "root", None) or (HF_LEROBOT_HOME / dataset.repo_id if dataset else None)
    task = dataset_task(root) if root is not None else None
    env = getattr(cfg, "env", None)
    if task is None and getattr(env, "type", None) == ENV_TYPE:
        task = {"type": ENV_TYPE, **env.to_dict()}
    return None if task is None else write_checkpoint_task(task, directory)
