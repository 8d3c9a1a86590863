"""A fast-path training run's checkpoints, in ``lerobot-train``'s layout: written with LeRobot's own
``save_checkpoint`` (``checkpoints/<step>/pretrained_model`` and ``training_state``, ``last`` pointing at the
newest) with the run as LeRobot's ``TrainPipelineConfig``, and pushed to the Hub as ``lerobot-train`` pushes them.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lerobot_pnp.outputs import OutputFolder
from lerobot_pnp.policy import PnpLstmPolicy

from .config import TrainFastConfig

logger = logging.getLogger(__name__)


@dataclass
class TrainingRun:
    """What a checkpoint needs, gathered once: the run's config and folder, the policy, its optimiser, scheduler
    and processors."""

    cfg: TrainFastConfig
    folder: OutputFolder  # the output folder, held for the run
    total_steps: int
    policy: PnpLstmPolicy
    optimizer: Any
    scheduler: Any
    preprocessor: Any
    postprocessor: Any
    opt_cfg: Any
    sched_cfg: Any

    @property
    def out_dir(self) -> Path:
        return self.folder.path

    def train_config(self, step: int):
        """The run as LeRobot's ``TrainPipelineConfig``: what a checkpoint's ``train_config.json`` and a pushed
        model card hold."""
        from lerobot.configs.default import DatasetConfig
        from lerobot.configs.train import TrainPipelineConfig

        cfg = self.cfg
        return TrainPipelineConfig(
            dataset=DatasetConfig(repo_id=cfg.dataset_repo_id, root=cfg.dataset_root, video_backend="pyav"),
            policy=self.policy.config,
            output_dir=self.out_dir,
            job_name="pnp_lstm_train_fast",
            seed=cfg.seed,
            num_workers=0,
            batch_size=cfg.batch_size,
            steps=self.total_steps,
            env_eval_freq=0,
            save_freq=step,
            optimizer=self.opt_cfg,
            scheduler=self.sched_cfg,
        )

    def save(self, step: int) -> Path:
        from lerobot.common.train_utils import get_step_checkpoint_dir, save_checkpoint, update_last_checkpoint

        cfg, train_cfg = self.cfg, self.train_config(step)
        ckpt = get_step_checkpoint_dir(self.out_dir, self.total_steps, step)
        save_checkpoint(
            checkpoint_dir=ckpt,
            step=step,
            cfg=train_cfg,
            policy=self.policy,
            optimizer=self.optimizer,
            scheduler=self.scheduler,
            preprocessor=self.preprocessor,
            postprocessor=self.postprocessor,
            batch_size=cfg.batch_size,
        )
        # The task the data was recorded in travels with the checkpoint (written, validated, by the policy's
        # save: PnpLstmPolicy._save_pretrained), so lerobot-eval finds it from any folder.
        update_last_checkpoint(ckpt)
        return ckpt / "pretrained_model"

    def push(self, step: int) -> None:
        """``--policy.push_to_hub``: the final policy (with its recorded task), its processors and a model card to
        ``--policy.repo_id``, as ``lerobot-train`` pushes them."""
        repo_id = self.policy.config.repo_id
        logger.info("Pushing the policy and its processors to the Hub: %s", repo_id)
        self.policy.push_model_to_hub(self.train_config(step))
        self.preprocessor.push_to_hub(repo_id)
        self.postprocessor.push_to_hub(repo_id)
