"""``lerobot-pnp generate --executor slurm``: the shard array and the merge job submitted to SLURM, and the job
ids a submission records beside the work folder (``slurm.json``), read back when the command runs again while
they may still be running.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from lerobot_pnp.dataset.executors import console_to_file, submit_slurm
from lerobot_pnp.dataset.merge import MergeShards
from lerobot_pnp.dataset.shards import GenerateShard, keep_valid_shards
from lerobot_pnp.dataset.validation import WORK_DIR
from lerobot_pnp.dataset.workdir import resume_advice
from lerobot_pnp.outputs import write_json_atomic


def recorded_slurm_jobs(work: Path) -> list[str]:
    """The SLURM job ids a submission recorded; only numeric ids are read (they go to ``squeue -j``)."""
    try:
        ids = json.loads((work / "slurm.json").read_text())["job_ids"]
    except (OSError, ValueError, KeyError, TypeError):
        return []
    return [i for i in ids if isinstance(i, str) and i.isdigit()] if isinstance(ids, list) else []


def submit(cfg: Any, root: Path, run: dict, logs: Path) -> dict:
    """``--executor slurm``: submit the shard array and the merge job of ``cfg`` (a ``GenerateConfig``), record their
    ids, return at once."""
    work = root / WORK_DIR
    tasks = run["tasks"]
    reused = keep_valid_shards(work, logs / "shards", cfg.num_episodes, tasks)
    shard_step = GenerateShard(
        work=str(work), repo_id=cfg.repo_id, env=run["env"], seed=cfg.seed, num_episodes=cfg.num_episodes,
        max_retries=cfg.max_retries,
    )  # fmt: skip
    with console_to_file(logs / "console.log"):
        job_ids = submit_slurm(shard_step, MergeShards(str(root)), tasks, cfg.slurm, logs, cfg.workers)
    write_json_atomic(work / "slurm.json", {"job_ids": job_ids, "logging_dir": str(logs)}, indent=2)
    return {
        "root": str(root),
        "status": "submitted",
        "executor": "slurm",
        "job_ids": job_ids,
        "shards": tasks,
        "episodes_reused": reused,
        "logging_dir": str(logs),
        "next": f"watch: squeue -j {','.join(job_ids)}; done when {root}/{WORK_DIR} is gone "
        f"(a failed task: {resume_advice(cfg.overwrite)})",
    }
