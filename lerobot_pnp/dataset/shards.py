"""One shard = one datatrove task: rank ``k`` of ``T`` simulates a consecutive block of episode slots and
writes it as a finalized LeRobotDataset (the pattern of LeRobot's ``examples/port_datasets/slurm_port_shards.py``).

The block of rank ``k`` is slots ``[k*N//T, (k+1)*N//T)``; a slot's content depends on (seed, N, slot) only
(``episodes.py``), so the merged dataset is the same whatever the executor, number of tasks or workers.
A shard is written into ``shard-<k>.tmp`` and renamed when finalized: a folder without the suffix is whole.
Datatrove marks the rank complete (``logs/completions/<k>``) only after ``run`` returns, and a rerun
skips completed ranks; ``shard_is_valid`` double-checks them before they are reused (and lets a resume adopt a
whole shard whose process was killed before its completion record).
"""

from __future__ import annotations

import json
import logging
import os
import time
from pathlib import Path

from datatrove.pipeline.base import PipelineStep

from lerobot_pnp.dataset.episodes import episode_frames, make_recording_env, simulate_slot
from lerobot_pnp.dataset.executors import die_with_forking_parent, owner_alive
from lerobot_pnp.dataset.schema import ROBOT_TYPE, dataset_features, saves_without_image_embedding
from lerobot_pnp.dataset.validation import validate_dataset
from lerobot_pnp.dataset.workdir import disk_error
from lerobot_pnp.errors import DatasetError, PnPError
from lerobot_pnp.outputs import remove_path

SHARD_FILE = "pnp_shard.json"  # inside a finished shard: its slots, seeds and expert failures
_ENVS: dict = {}


def shard_range(num_episodes: int, tasks: int, rank: int) -> tuple[int, int]:
    """The consecutive episode slots of shard ``rank`` of ``tasks`` (sizes differ by at most one)."""
    return rank * num_episodes // tasks, (rank + 1) * num_episodes // tasks


def shard_dir(work: Path, rank: int) -> Path:
    return Path(work) / "shards" / f"shard-{rank:05d}"


def read_shard_record(work: Path, rank: int) -> dict:
    return json.loads((shard_dir(work, rank) / SHARD_FILE).read_text())


def shard_is_valid(work: Path, rank: int, num_episodes: int, tasks: int) -> bool:
    """A completed rank's shard is reusable: whole, readable, and holding exactly its slots."""
    start, stop = shard_range(num_episodes, tasks, rank)
    try:
        record = read_shard_record(work, rank)
        info = validate_dataset(shard_dir(work, rank))
    except (OSError, ValueError, PnPError):
        return False
    seeds = record.get("seeds", [])
    return (
        record.get("start") == start
        and record.get("stop") == stop
        and len(seeds) == len(set(seeds)) == stop - start == info["total_episodes"]
    )


class GenerateShard(PipelineStep):
    """Datatrove step: write shard ``rank`` of ``world_size`` (a finalized LeRobotDataset)."""

    name = "expert episodes -> LeRobotDataset shard"
    type = "lerobot_pnp"

    def __init__(
        self,
        work: str,
        repo_id: str,
        env: dict,
        seed: int,
        num_episodes: int,
        max_retries: int,
        parent_pid: int | None = None,
    ):
        super().__init__()
        self.work, self.repo_id, self.env = str(work), repo_id, env
        self.seed, self.num_episodes, self.max_retries = seed, num_episodes, max_retries
        self.parent_pid = parent_pid

    def run(self, data=None, rank: int = 0, world_size: int = 1):
        die_with_forking_parent(self.parent_pid)
        try:
            record = self.write(rank, world_size)
        except PnPError as err:
            raise DatasetError(f"shard {rank}: {err}") from None
        except OSError as err:
            raise disk_error(Path(self.work).parent, err) from None
        self.stat_update("episodes", value=len(record["seeds"]))
        self.stat_update("expert_failures", value=len(record["failures"]))
        return None

    def write(self, rank: int, world_size: int) -> dict:
        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

        quiet_and_single_threaded()
        start, stop = shard_range(self.num_episodes, world_size, rank)
        final = shard_dir(self.work, rank)
        tmp = final.with_name(final.name + ".tmp")
        for path in (tmp, final):  # a rank not marked complete is redone from scratch
            remove_path(path)
        progress = Path(self.work) / "progress" / f"{rank:05d}"
        progress.parent.mkdir(parents=True, exist_ok=True)
        env_cfg = BaxterPnPEnvConfig.from_dict(self.env)
        key = json.dumps(self.env, sort_keys=True)
        if key not in _ENVS:  # one env per worker process: a worker runs many ranks, reset(seed) rebuilds state
            _ENVS[key] = make_recording_env(env_cfg)
        env = _ENVS[key]
        features = dataset_features(env_cfg)
        ds = LeRobotDataset.create(
            repo_id=f"{self.repo_id}_shard{rank:05d}",
            fps=env_cfg.fps,
            features=features,
            root=tmp,
            robot_type=ROBOT_TYPE,
            use_videos=bool(env_cfg.cameras),
            video_backend="pyav",
            metadata_buffer_size=max(10, stop - start),
        )
        seeds, failures = [], []
        sim_s = write_s = 0.0
        with saves_without_image_embedding(features):
            for slot in range(start, stop):
                if self.parent_pid not in (None, os.getpid()) and not owner_alive(self.parent_pid):
                    os._exit(1)  # where the watch of die_with_forking_parent is unavailable
                t0 = time.perf_counter()
                ep = simulate_slot(env, self.seed, self.num_episodes, slot, self.max_retries, failures)
                t1 = time.perf_counter()
                for frame in episode_frames(ep, getattr(env, "pixels", None), env_cfg.cameras):
                    ds.add_frame(frame)
                ds.save_episode()
                write_s += time.perf_counter() - t1
                sim_s += t1 - t0
                seeds.append(ep.seed)
                progress.write_text(f"{len(seeds)} {len(failures)}")
        t0 = time.perf_counter()
        ds.finalize()
        record = {"rank": rank, "start": start, "stop": stop, "seeds": seeds, "failures": failures}
        record.update(sim_s=round(sim_s, 3), write_s=round(write_s + time.perf_counter() - t0, 3))
        (tmp / SHARD_FILE).write_text(json.dumps(record, indent=1))
        os.replace(tmp, final)
        return record


def quiet_and_single_threaded() -> None:
    """One thread per worker (workers are the parallelism) and no per-episode progress bars from `datasets`."""
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = "1"
    import datasets
    import torch

    torch.set_num_threads(1)
    datasets.disable_progress_bars()
    logging.getLogger("lerobot.utils.import_utils").setLevel(logging.ERROR)


def keep_valid_shards(work: Path, logs: Path, num_episodes: int, tasks: int) -> int:
    """Keep a rank's shard only if it validates; return the number of episodes kept.

    A rank marked complete whose shard does not validate loses its mark (it is redone). A whole shard (renamed
    from ``.tmp``) without a mark is one whose process was killed between the rename and datatrove's
    completion record: it validates, so it is marked complete and kept instead of being simulated again.
    """
    done = logs / "completions"
    kept = 0
    for rank in range(tasks):
        mark = done / f"{rank:05d}"
        if not mark.exists() and not shard_dir(work, rank).is_dir():
            continue
        if shard_is_valid(work, rank, num_episodes, tasks):
            kept += len(json.loads((shard_dir(work, rank) / "pnp_shard.json").read_text())["seeds"])
            if not mark.exists():
                mark.parent.mkdir(parents=True, exist_ok=True)
                mark.touch()
        elif mark.exists():
            mark.unlink()
    return kept
