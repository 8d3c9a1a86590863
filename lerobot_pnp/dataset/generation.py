"""``lerobot-pnp generate``: expert demonstrations as one LeRobotDataset v3.0, at any scale.

The task (control mode, fps, cameras, object region, ...) is the env config ``--env.*``; this config holds
only how much to generate and how to run it. The run is a datatrove pipeline (``shards.py``): rank ``k`` of
``--tasks`` writes a shard of consecutive episode slots, ``LocalPipelineExecutor`` runs the ranks on this
machine (``--workers`` at a time, default one per core) or ``SlurmPipelineExecutor`` on a cluster
(``--executor slurm``); then ``merge.py`` aggregates, verifies, splits and commits. Interrupted runs
(kill -9, a failed task, a full disk) finish with ``--resume``: completed ranks are skipped (datatrove's
completion records, double-checked by shard validation; a whole shard whose record the kill caught is adopted),
the others are redone from scratch.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from lerobot_pnp.dataset.annotations import annotate_subtasks
from lerobot_pnp.dataset.executors import (
    ProgressBar,
    SlurmOptions,
    active_slurm_jobs,
    console_to_file,
    default_workers,
    run_local,
)
from lerobot_pnp.dataset.layout import recorded_task_path
from lerobot_pnp.dataset.merge import GENERATION_FILE, merge_and_commit
from lerobot_pnp.dataset.shards import GenerateShard, keep_valid_shards
from lerobot_pnp.dataset.slurm_submit import recorded_slurm_jobs, submit
from lerobot_pnp.dataset.splits import TRAIN_FRACTION
from lerobot_pnp.dataset.validation import WORK_DIR, read_json, validate_dataset
from lerobot_pnp.dataset.workdir import (
    DATASET_ENTRIES,
    GENERATE_ENTRIES,
    RUN_FILE,
    DatasetRoot,
    disk_error,
    episodes_recorded,
    read_run_record,
    resume_advice,
)
from lerobot_pnp.errors import ConfigError, DatasetError, OtherSettingsError
from lerobot_pnp.outputs import LOCK_FILE, remove_path, write_json_atomic
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

EXECUTORS = ("local", "slurm")
MAX_EPISODES = 10_000_000  # above this, --allow_huge must say it is meant (memory and disk grow with N)
# Episodes per shard when --tasks is 0 (auto); SLURM tasks are 10x larger (a task start costs seconds).
SHARD_SIZE = {"keyframe": 100, "dense": 20, "cameras": 25}
# At most this many auto shards locally: LeRobot's ``aggregate_datasets`` appends each shard's videos by rewriting
# the growing merged file, so the merge costs about the square of the shard count; local workers are few anyway.
MAX_LOCAL_SHARDS = 64
# What a resumed run must share with the run on disk.
_CONTENT_FIELDS = ("repo_id", "seed", "num_episodes", "max_retries", "train_fraction", "env")


@dataclass
class GenerateConfig:
    """``lerobot-pnp generate``: expert demonstrations as a LeRobotDataset v3.0."""

    repo_id: str = "local/baxter_pnp_keyframe"  # the dataset's LeRobot repo id (owner/name), also its default folder
    root: str | None = None  # output folder; default outputs/datasets/<repo_id>
    num_episodes: int = 1400  # episodes to record (slots; an expert failure is re-seeded, see max_retries)
    seed: int = 0  # episode slot i uses seed + i (retries: seed + i + num_episodes * r)
    env: BaxterPnPEnvConfig = field(default_factory=BaxterPnPEnvConfig)  # the task: --env.control_mode dense ...
    executor: str = "local"  # local (this machine) | slurm (sbatch array + merge job)
    tasks: int = 0  # shards = datatrove tasks; 0 = auto (about 100 keyframe episodes each, locally)
    workers: int = 0  # local: tasks run at once (0 = one per core); slurm: max array tasks at once (0 = no cap)
    slurm: SlurmOptions = field(default_factory=SlurmOptions)
    logging_dir: str | None = None  # datatrove logs; default ROOT/.pnp_work/logs (local), ROOT.logs (slurm)
    train_fraction: float = TRAIN_FRACTION  # first episodes -> "train", the rest -> "test" (meta/info.json "splits")
    max_retries: int = 10  # reseeds per slot when the expert fails
    resume: bool = False  # finish an interrupted run in root (completed shards are kept)
    overwrite: bool = False  # replace the dataset (or interrupted run) generate wrote in root; other files are kept
    allow_huge: bool = False  # allow num_episodes above 10 million
    progress: bool = True  # one tqdm bar (datatrove's logs go to the logging folder)
    # the FSM phases as LeRobot subtask annotations (language_persistent rows; dataset/annotations.py); opt-in
    # because the extra columns change the data files (the paper dataset's hash is fixed)
    subtask_annotations: bool = False

    def __post_init__(self):
        if isinstance(self.env, dict):
            self.env = BaxterPnPEnvConfig.from_dict(self.env)
        if isinstance(self.slurm, dict):
            self.slurm = SlurmOptions(**self.slurm)
        if not (isinstance(self.num_episodes, int) and self.num_episodes >= 1):
            raise ConfigError(f"num_episodes must be an integer >= 1, got {self.num_episodes!r}")
        if self.num_episodes > MAX_EPISODES and not self.allow_huge:
            raise ConfigError(
                f"num_episodes={self.num_episodes:,} is above {MAX_EPISODES:,}; pass --allow_huge if you mean it "
                "(disk grows with N; split the job across a SLURM cluster with --executor slurm)"
            )
        if not (isinstance(self.seed, int) and self.seed >= 0 and self.seed + self.num_episodes * 12 < 2**63):
            raise ConfigError(f"seed must be an integer in [0, 2**63) with room for the episode seeds, got {self.seed}")
        if self.executor not in EXECUTORS:
            raise ConfigError(f"executor must be one of {EXECUTORS}, got {self.executor!r}")
        for name in ("tasks", "workers", "max_retries"):
            if getattr(self, name) < 0:
                raise ConfigError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.tasks > self.num_episodes:
            raise ConfigError(f"tasks ({self.tasks}) must be <= num_episodes ({self.num_episodes})")
        if not 0 < self.train_fraction <= 1:
            raise ConfigError(f"train_fraction must be in (0, 1], got {self.train_fraction}")
        if self.resume and self.overwrite:
            raise ConfigError("pass either --resume or --overwrite, not both")
        if "/" not in self.repo_id:
            raise ConfigError(f"repo_id must look like 'user/name', got {self.repo_id!r}")
        if self.subtask_annotations and self.executor != "local":
            raise ConfigError(
                f"subtask_annotations is written after the local merge; not available with executor={self.executor!r}"
            )

    @property
    def output_root(self) -> Path:
        return Path(self.root) if self.root else Path("outputs/datasets") / self.repo_id

    def auto_tasks(self, workers: int) -> int:
        kind = "cameras" if self.env.cameras else self.env.control_mode
        size = SHARD_SIZE[kind] * (10 if self.executor == "slurm" else 1)
        tasks = math.ceil(self.num_episodes / size)
        if self.executor == "local":
            # every worker gets a shard while a shard keeps half its size: a smaller one would cost its worker's
            # start-up (LeRobot and torch imported in a spawned process) more than it saves
            tasks = max(min(tasks, MAX_LOCAL_SHARDS), min(workers, self.num_episodes // max(1, size // 2)))
        return tasks

    def run_record(self, tasks: int) -> dict:
        """The settings of a run (``.pnp_work/run.json``): what a resume must match, and the shard layout."""
        d = asdict(self)
        return {**{k: d[k] for k in _CONTENT_FIELDS if k != "env"}, "env": self.env.to_dict(), "tasks": tasks}


def generate(cfg: GenerateConfig) -> dict:
    """Generate ``cfg.num_episodes`` successful expert episodes into ``cfg.output_root``; return a summary."""
    t_start = time.perf_counter()
    root = cfg.output_root.resolve()  # the root given as a link is the user's choice; links inside are refused
    if root.is_file():
        raise DatasetError(f"{root} is a file, not a dataset folder")
    made = [p for p in (root, *root.parents) if not p.exists()]  # the folders this run creates
    try:
        with DatasetRoot(root) as out:  # locked before anything is deleted; a root that existed before stays
            try:
                return _generate_locked(cfg, out, t_start)
            except Exception:
                if not (root / WORK_DIR).exists():
                    out.release()  # no run left to write what it claimed
                if made and not any(p.name != LOCK_FILE for p in root.iterdir()):
                    _remove_made(made)  # made by this run, which leaves nothing in them: gone again
                raise
    except OSError as err:
        raise disk_error(root, err, resume_advice(cfg.overwrite)) from None
    except KeyboardInterrupt:
        raise DatasetError(
            f"interrupted; the finished shards in {root} are kept: {resume_advice(cfg.overwrite)}"
        ) from None


def _remove_made(folders: list[Path]) -> None:
    """Remove ``folders`` (a root and the parents made for it, innermost first) while each is empty."""
    (folders[0] / LOCK_FILE).unlink(missing_ok=True)
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:  # something else was written there meanwhile: keep it
            return


def _root_state_for(cfg: GenerateConfig, out: DatasetRoot) -> str:
    """The state of the root this run starts from, after ``--overwrite``; DatasetError when it may not start.

    Every entry a run writes is claimed here, before anything is written or deleted (the user's entries of
    those names are refused). ``--overwrite`` deletes an interrupted run's work folder; a finished dataset
    stays until the new one is committed in its place."""
    root, work = out.path, out.path / WORK_DIR
    state = out.state()
    jobs = recorded_slurm_jobs(work)
    if state == "interrupted" and active_slurm_jobs(jobs) and (cfg.overwrite or cfg.resume):
        raise DatasetError(
            f"SLURM jobs {jobs} of the generation in {root} are still queued or running; wait for them "
            f"(squeue -j {','.join(jobs)}) or cancel them (scancel) first"
        )
    if cfg.overwrite and state == "foreign":
        raise DatasetError(
            f"refusing to --overwrite {root}: it holds no dataset (no meta/info.json), only files `generate` did "
            "not write; drop --overwrite to write the dataset beside them, or pick another --root"
        )
    if state == "foreign":
        state = "empty"  # the user's files stay, beside the dataset
    if state != "empty" and not (cfg.resume or cfg.overwrite):
        what = {"interrupted": "an interrupted generation", "complete": "a dataset"}[state]
        raise DatasetError(
            f"{root} already exists ({what}); pass --resume to finish/keep it or --overwrite to replace it"
        )
    if state == "complete" and cfg.resume:
        return state
    out.claim(*GENERATE_ENTRIES)
    if cfg.overwrite:
        out.remove(WORK_DIR)
        return "empty"
    return state


def _verify_complete(cfg: GenerateConfig, out: DatasetRoot) -> dict:
    """``--resume`` on a finished dataset: verify it matches this run's settings and report it."""
    root = out.path
    info = validate_dataset(root)
    record = read_json(root / GENERATION_FILE, "generation record")
    made = record.get("generation") if isinstance(record, dict) else None
    env = read_json(recorded_task_path(root), "env")
    if not isinstance(made, dict) or not isinstance(env, dict):
        raise DatasetError(f"{root / GENERATION_FILE} or {recorded_task_path(root)} is not a record of this package")
    _check_same_run(made, cfg, env)
    if cfg.subtask_annotations:
        out.claim(*(n for n in DATASET_ENTRIES if (root / n).exists()))  # rewritten: only a dataset of its own
        annotate_subtasks(root)
    return {"root": str(root), "status": "already complete", "episodes": info["total_episodes"],
            "frames": info["total_frames"], "splits": info.get("splits")}  # fmt: skip


def _generate_locked(cfg: GenerateConfig, out: DatasetRoot, t_start: float) -> dict:
    """A run from the state the root is in. A fresh run that fails before its first episode leaves the root as
    it was (its work folder removed), so that the corrected command is a fresh start."""
    state = _root_state_for(cfg, out)
    if state == "complete":
        return _verify_complete(cfg, out)
    try:
        return _run(cfg, out, state, t_start)
    except Exception:
        if state == "empty" and not episodes_recorded(out.path / WORK_DIR):
            out.remove(WORK_DIR)
        raise


def _run_settings(cfg: GenerateConfig, out: DatasetRoot, state: str, workers: int) -> dict:
    """The run's settings: recorded on a fresh start, checked on a resume (the shard layout comes from disk)."""
    work = out.work()
    run_path = work / RUN_FILE
    if state == "interrupted" and run_path.is_file():
        run = read_run_record(work)
        _check_same_run(run, cfg, run["env"])
        if cfg.tasks and cfg.tasks != run["tasks"]:
            raise ConfigError(f"--resume with --tasks {cfg.tasks} but the run on disk has {run['tasks']} shards")
        return run
    out.remove(WORK_DIR)  # killed before the settings were written: nothing in it is usable
    run = cfg.run_record(cfg.tasks or cfg.auto_tasks(workers))
    write_json_atomic(run_path, run, indent=2)
    return run


def _run(cfg: GenerateConfig, out: DatasetRoot, state: str, t_start: float) -> dict:
    root, work = out.path, out.path / WORK_DIR
    workers = cfg.workers or default_workers()
    run = _run_settings(cfg, out, state, workers)
    tasks = run["tasks"]
    logs = Path(cfg.logging_dir).resolve() if cfg.logging_dir else None
    if cfg.executor == "slurm":
        return submit(cfg, root, run, logs or root.with_name(root.name + ".logs"))
    logs = logs or work / "logs"

    # Completed ranks whose shard does not validate (or stale records) are redone.
    reused = keep_valid_shards(work, logs, cfg.num_episodes, tasks)
    shard_step = GenerateShard(
        work=str(work), repo_id=cfg.repo_id, env=run["env"], seed=cfg.seed, num_episodes=cfg.num_episodes,
        max_retries=cfg.max_retries, parent_pid=os.getpid(),
    )  # fmt: skip
    progress_dir = work / "progress"
    remove_path(progress_dir)
    t_sim = time.perf_counter()
    with console_to_file(logs / "console.log") as terminal:
        with ProgressBar(progress_dir, cfg.num_episodes, terminal, cfg.progress, initial=reused):
            try:
                run_local(shard_step, tasks, workers, logs)
            except DatasetError as err:
                if state == "empty" and not episodes_recorded(work) and logs.is_relative_to(work):
                    raise  # nothing to resume: the work folder goes, and its logs with it
                raise DatasetError(f"{err} (task logs: {logs}/logs)") from None
        sim_wall = time.perf_counter() - t_sim
        t_merge = time.perf_counter()
        summary = merge_and_commit(out)
        if cfg.subtask_annotations:
            summary["subtask_rows"] = annotate_subtasks(root)
    merge_wall = time.perf_counter() - t_merge
    summary.update(
        status="resumed" if reused else "generated",
        episodes_reused=reused,
        workers=max(1, min(workers, tasks)),
        executor="local",
        wall_s=round(time.perf_counter() - t_start, 2),
        generate_wall_s=round(sim_wall, 2),
        merge_wall_s=round(merge_wall, 2),
        episodes_per_s=round((cfg.num_episodes - reused) / sim_wall, 2) if cfg.num_episodes > reused else None,
    )
    return summary


def _check_same_run(recorded: dict, cfg: GenerateConfig, recorded_env: dict) -> None:
    """OtherSettingsError naming each content setting on disk that differs from ``cfg``'s."""
    mine = cfg.run_record(0)
    recorded = {**recorded, "env": {k: v for k, v in recorded_env.items() if k != "type"}}
    diff = {k: (recorded.get(k), mine[k]) for k in _CONTENT_FIELDS if _norm(recorded.get(k)) != _norm(mine[k])}
    if diff:
        if "env" in diff:
            a, b = diff.pop("env")
            diff.update({f"env.{k}": (a.get(k), b[k]) for k in b if _norm(a.get(k)) != _norm(b[k])})
        details = ", ".join(f"{k}: on disk {a!r} vs requested {b!r}" for k, (a, b) in diff.items())
        raise OtherSettingsError(
            f"--resume with different settings than the run on disk ({details}); use the same settings or --overwrite"
        )


def _norm(v):
    return json.loads(json.dumps(v, default=list))
