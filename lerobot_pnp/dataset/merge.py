"""The last step of a generation: merge the shards with LeRobot's ``aggregate_datasets``, verify, split, commit.

Runs in the `generate` process after a local run, or as the one-task SLURM job that depends on the shard
array (``slurm_aggregate_shards.py`` in LeRobot's examples). The merge is built in ``.pnp_work/merged``,
verified (episode count, seeds in slot order, stats recomputed from the data), given the train/test split
(``meta/info.json`` "splits"), the env config (``meta/baxter_pnp_env.json``) and the generation record
(``meta/pnp_generate.json``), then committed: moved into the root in place of the previous dataset's entries
(``DatasetRoot.commit``); the work folder is removed last.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from datatrove.pipeline.base import PipelineStep

from lerobot_pnp import robot
from lerobot_pnp.dataset.layout import is_dataset
from lerobot_pnp.dataset.shards import SHARD_FILE, read_shard_record, shard_dir
from lerobot_pnp.dataset.splits import split_of
from lerobot_pnp.dataset.validation import WORK_DIR, read_json, verify_dataset
from lerobot_pnp.dataset.workdir import DatasetRoot, resume_advice
from lerobot_pnp.errors import DatasetError
from lerobot_pnp.outputs import remove_path, write_json_atomic
from lerobot_pnp.recorded_files import GENERATION_FILE


def merge_and_commit(out: DatasetRoot) -> dict:
    """Merge the shards of the run in the root's work folder into the root; return a summary."""
    from lerobot.datasets.aggregate import aggregate_datasets
    from lerobot.datasets.io_utils import load_info, write_info

    from lerobot_pnp.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.recorded_files import write_recorded
    from lerobot_pnp.version import __version__

    root, work = out.path, out.work()
    run = read_json(work / "run.json", "generation settings")
    n, tasks = run["num_episodes"], run["tasks"]
    records = []
    for rank in range(tasks):
        try:
            records.append(read_shard_record(work, rank))
        except (OSError, ValueError):
            raise DatasetError(f"shard {rank} of {root} is missing or incomplete; {resume_advice()}") from None
    seeds = [s for r in records for s in r["seeds"]]
    if len(seeds) != n or len(set(seeds)) != n:
        raise DatasetError(
            f"shards hold {len(seeds)} episodes ({len(set(seeds))} distinct seeds), expected {n} distinct; "
            "rerun with --overwrite"
        )
    merged = work / "merged"
    remove_path(merged)
    roots = [shard_dir(work, rank) for rank in range(tasks)]
    if tasks == 1:
        shutil.copytree(roots[0], merged, ignore=shutil.ignore_patterns(SHARD_FILE))
    else:
        aggregate_datasets(
            repo_ids=[f"{run['repo_id']}_shard{rank:05d}" for rank in range(tasks)],
            aggr_repo_id=run["repo_id"],
            roots=roots,
            aggr_root=merged,
            concatenate_data=False,  # one data file per shard: a linear-time merge (no rewrites)
        )
        fix_index_stats(merged)
    info = load_info(merged)
    info.splits = split_of(n, run["train_fraction"])
    write_info(info, merged)
    check = verify_dataset(merged, expected_seeds=seeds)
    write_recorded(BaxterPnPEnvConfig.from_dict(run["env"]), merged)
    failures = [f for r in records for f in r["failures"]]
    write_json_atomic(
        merged / GENERATION_FILE,
        {
            "generation": {k: run[k] for k in ("repo_id", "seed", "num_episodes", "max_retries", "train_fraction")},
            "seed_rule": "slot i, retry r -> seed + i + num_episodes * r",
            "task": robot.TASK,
            "shards": tasks,
            "failures": failures,
            "lerobot_pnp_version": __version__,
        },
        indent=2,
    )
    out.commit(merged)
    causes: dict[str, int] = {}
    for f in failures:
        causes[f["cause"]] = causes.get(f["cause"], 0) + 1
    return {
        "root": str(root),
        "repo_id": run["repo_id"],
        "control_mode": run["env"]["control_mode"],
        "fps": info.fps,
        "episodes": check["total_episodes"],
        "frames": check["total_frames"],
        "splits": info.splits,
        "shards": tasks,
        "expert_failures": len(failures),
        "failure_causes": causes,
        "simulate_cpu_s": round(sum(r.get("sim_s", 0) for r in records), 2),
        "write_cpu_s": round(sum(r.get("write_s", 0) for r in records), 2),
    }


INDEX_COLUMNS = ("episode_index", "index")  # numbered afresh by a merge


def fix_index_stats(root: Path) -> None:
    """Recompute ``meta/stats.json``'s ``episode_index`` and ``index`` from a merged dataset's data.

    LeRobot's ``aggregate_datasets`` aggregates the sources' dataset-level stats, which describe each
    source's own numbering (0..), not the merged one (the per-episode stats it does shift)."""
    import numpy as np
    import pyarrow.dataset as pads
    from lerobot.datasets.compute_stats import get_feature_stats
    from lerobot.datasets.io_utils import load_stats, write_stats

    stats = load_stats(root)
    names = [n for n in INDEX_COLUMNS if stats and n in stats]
    if not names:
        return
    files = sorted(str(p) for p in (root / "data").rglob("*.parquet"))
    table = pads.dataset(files, format="parquet").to_table(columns=names)
    for name in names:
        values = table[name].to_numpy().astype(np.float64).reshape(-1, 1)
        fresh = get_feature_stats(values, axis=0, keepdims=False)
        stats[name] = {
            k: np.asarray(fresh[k], dtype=np.asarray(old).dtype).reshape(np.shape(old)) if k in fresh else old
            for k, old in stats[name].items()
        }
    write_stats(stats, root)


class MergeShards(PipelineStep):
    """Datatrove step (one task) for SLURM: merge and commit once every shard rank has completed."""

    name = "merge shards -> one LeRobotDataset"
    type = "lerobot_pnp"

    def __init__(self, root: str):
        super().__init__()
        self.root = root

    def run(self, data=None, rank: int = 0, world_size: int = 1):
        root = Path(self.root)
        if not (root / WORK_DIR).exists() and is_dataset(root):
            return None  # already merged (a requeued merge job)
        with DatasetRoot(root) as out:
            merge_and_commit(out)
        return None
