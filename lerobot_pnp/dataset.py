"""Expert demonstrations as a LeRobotDataset v3.0 (``lerobot-pnp generate`` / ``lerobot-pnp push``).

Everything is written with LeRobot's own writer (``LeRobotDataset.create / add_frame / save_episode /
finalize``) and merged with LeRobot's ``aggregate_datasets``; the result is a plain LeRobot folder that the
stock loader, ``lerobot-train`` and ``lerobot-dataset-viz`` read.

Two representations:

* ``keyframe`` (the paper's): one episode = the 10 FSM states, fps 1 (nominal).
* ``dense``: the same features at the control rate (``fps``), optionally with camera videos.

Per frame: ``observation.state`` (7 joints + gripper), ``observation.environment_state`` (cube xyz),
``action``, ``next.done``, ``next.success``, ``phase.index`` (FSM state 0..9), ``phase.subtask``
(0 pick, 1 place), ``episode.seed`` (the expert seed that re-simulates the episode exactly) and the task
string. ``phase.*`` and ``episode.*`` are deliberately not ``observation.*`` so LeRobot never feeds them to
a policy.

Layout and crash safety (scale by design)
-----------------------------------------
Episode slot ``i`` (0 <= i < N) is simulated with seed ``seed + i``; when the expert fails on it, retry
``r`` uses ``seed + i + N * r`` (disjoint from every other slot's first try). Slots are grouped into shards of
``shard_size`` consecutive slots. While a run is in progress the output root holds only a work folder::

    ROOT/.pnp_work/manifest.json            the config the run was started with
    ROOT/.pnp_work/shards/shard-00003.tmp/  a shard being written (discarded on resume)
    ROOT/.pnp_work/shards/shard-00003/      a finished shard: a finalized LeRobotDataset (atomic rename)
    ROOT/.pnp_work/merged/                  the aggregate being built

Worker processes each simulate and write whole shards, so the content depends on the slot range only (not
on the number of workers). When every shard is done they are merged in slot order with
``lerobot.datasets.aggregate.aggregate_datasets``, the merge is verified (episode count, distinct seeds,
frame count, stats recomputed from the data), the 80/20 split is written into ``meta/info.json`` and the
merged folder is moved into ROOT. ``.pnp_work`` is removed last: a ROOT without it is complete.
A ``kill -9`` at any point loses at most the shards in progress; ``--resume`` keeps the finished shards.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import queue
import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError, DatasetError, ExpertFailure, UnreachableError

logger = logging.getLogger(__name__)

REPRESENTATIONS = ("keyframe", "dense")
KEYFRAME_FPS = robot.KEYFRAME_FPS
ROBOT_TYPE = "baxter"
WORK_DIR = ".pnp_work"
TRASH_DIR = ".pnp_work.trash"
GENERATION_FILE = "meta/pnp_generate.json"
SHARD_FILE = "pnp_shard.json"
DEFAULT_SHARD_SIZE = {"keyframe": 100, "dense": 20, "cameras": 5}
# Fields of GenerateConfig that define the content; a resumed run must match them.
_CONTENT_FIELDS = (
    "repo_id",
    "num_episodes",
    "seed",
    "representation",
    "fps",
    "cameras",
    "image_height",
    "image_width",
    "speed",
    "max_retries",
    "train_fraction",
    "shard_size",
)


# ---------------------------------------------------------------------------------------------- configs
@dataclass
class GenerateConfig:
    """``lerobot-pnp generate``: expert demonstrations as a LeRobotDataset v3.0."""

    repo_id: str = "local/baxter_pnp_keyframe"
    root: str | None = None  # output folder; default outputs/datasets/<repo_id>
    num_episodes: int = 1400
    seed: int = 0  # episode slot i uses seed + i (retries: seed + i + num_episodes * r)
    representation: str = "keyframe"  # keyframe (10 FSM states per episode, fps 1) | dense (control rate)
    fps: int = 20  # dense only (keyframe datasets are fps 1)
    cameras: list[str] = field(default_factory=list)  # empty = no images; e.g. [front,wrist] (videos)
    image_height: int = 240
    image_width: int = 320
    speed: float = 1.0  # fraction of Baxter's joint velocity limits
    workers: int = 0  # worker processes; 0 = one per CPU core
    shard_size: int = 0  # episodes per shard; 0 = auto
    train_fraction: float = 0.8  # first episodes -> "train", the rest -> "test" (meta/info.json "splits")
    max_retries: int = 10  # reseeds per slot when the expert fails
    resume: bool = False  # finish an interrupted run in root (finished shards are kept)
    overwrite: bool = False  # delete an existing dataset in root first
    progress: bool = True  # tqdm progress bar

    def __post_init__(self):
        if self.representation not in REPRESENTATIONS:
            raise ConfigError(f"representation must be one of {REPRESENTATIONS}, got {self.representation!r}")
        if not (isinstance(self.num_episodes, int) and self.num_episodes >= 1):
            raise ConfigError(f"num_episodes must be an integer >= 1, got {self.num_episodes!r}")
        if self.seed < 0:
            raise ConfigError(f"seed must be >= 0, got {self.seed}")
        if self.representation == "keyframe":
            self.fps = KEYFRAME_FPS
        elif not 1 <= self.fps <= 500:
            raise ConfigError(f"fps must be in [1, 500], got {self.fps}")
        from lerobot_pnp.physics import CAMERAS

        self.cameras = list(self.cameras or [])
        unknown = [c for c in self.cameras if c not in CAMERAS]
        if unknown or len(set(self.cameras)) != len(self.cameras):
            raise ConfigError(f"cameras must be distinct names from {CAMERAS}, got {self.cameras}")
        if self.image_height < 8 or self.image_width < 8:
            raise ConfigError("image_height and image_width must be >= 8")
        if self.workers < 0 or self.shard_size < 0 or self.max_retries < 0:
            raise ConfigError("workers, shard_size and max_retries must be >= 0")
        if not 0 < self.train_fraction <= 1:
            raise ConfigError(f"train_fraction must be in (0, 1], got {self.train_fraction}")
        if self.resume and self.overwrite:
            raise ConfigError("pass either --resume or --overwrite, not both")
        if "/" not in self.repo_id:
            raise ConfigError(f"repo_id must look like 'user/name', got {self.repo_id!r}")

    @property
    def output_root(self) -> Path:
        return Path(self.root) if self.root else Path("outputs/datasets") / self.repo_id

    def env_kwargs(self) -> dict:
        return {
            "control_mode": self.representation,
            "fps": self.fps,
            "cameras": tuple(self.cameras),
            "image_size": (self.image_height, self.image_width),
            "speed": self.speed,
        }


@dataclass
class PushConfig:
    """``lerobot-pnp push``: upload a generated dataset to the Hugging Face Hub (tagged v3.0)."""

    repo_id: str = "local/baxter_pnp_keyframe"
    root: str | None = None  # default outputs/datasets/<repo_id>
    private: bool = False
    branch: str | None = None
    push_videos: bool = True
    connect_timeout_s: float = 5.0  # fail fast when the Hub cannot be reached

    @property
    def output_root(self) -> Path:
        return Path(self.root) if self.root else Path("outputs/datasets") / self.repo_id


# ---------------------------------------------------------------------------------------------- features
def dataset_features(representation: str = "keyframe", cameras=(), image_size=(240, 320)) -> dict:
    """LeRobot feature spec of a pnp dataset (the single place the columns are defined)."""
    scalar = {"shape": (1,), "names": None}
    features = {
        "observation.state": {"dtype": "float32", "shape": (robot.STATE_DIM,), "names": list(robot.STATE_NAMES)},
        "observation.environment_state": {
            "dtype": "float32",
            "shape": (robot.OBJECT_DIM,),
            "names": list(robot.OBJECT_NAMES),
        },
        "action": {"dtype": "float32", "shape": (robot.ACTION_DIM,), "names": list(robot.ACTION_NAMES)},
        "next.done": {"dtype": "bool", **scalar},
        "next.success": {"dtype": "bool", **scalar},
        "phase.index": {"dtype": "int64", **scalar},
        "phase.subtask": {"dtype": "int64", **scalar},
        "episode.seed": {"dtype": "int64", **scalar},
    }
    h, w = image_size
    for cam in cameras:
        features[f"observation.images.{cam}"] = {
            "dtype": "video",
            "shape": (h, w, 3),
            "names": ["height", "width", "channels"],
        }
    return features


# ---------------------------------------------------------------------------------------------- quiet helpers
def _quiet_libraries() -> None:
    """No per-episode 'Map' progress bars from `datasets` (they also cost time)."""
    import datasets

    datasets.disable_progress_bars()
    logging.getLogger("lerobot.utils.import_utils").setLevel(logging.ERROR)


def _single_thread() -> None:
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = "1"
    try:
        import torch

        torch.set_num_threads(1)
    except Exception:  # pragma: no cover - torch is a dependency, but threads are only a speed matter
        pass


# ---------------------------------------------------------------------------------------------- one shard
_ENV_CACHE: dict = {}


def _get_env(env_kwargs: dict):
    """One env per process and configuration (episodes are independent: reset(seed) rebuilds the state)."""

    import lerobot_pnp  # noqa: F401  (registers the gym ids in spawned workers)

    key = json.dumps(env_kwargs, sort_keys=True, default=list)
    if key not in _ENV_CACHE:
        kwargs = dict(env_kwargs)
        from lerobot_pnp.env_config import make_env

        h, w = kwargs["image_size"]
        env = make_env(
            None,
            control_mode=kwargs["control_mode"],
            fps=kwargs["fps"],
            cameras=list(kwargs["cameras"]),
            image_height=h,
            image_width=w,
            speed=kwargs["speed"],
        )
        if kwargs["cameras"]:
            env = _PixelRecorder(env)
        _ENV_CACHE[key] = env
    return _ENV_CACHE[key]


def _pixel_recorder_cls():
    import gymnasium as gym

    class PixelRecorder(gym.Wrapper):
        """Keeps the camera images of every observation the expert sees (reset + each step)."""

        def reset(self, **kwargs):
            obs, info = self.env.reset(**kwargs)
            self.pixels = [obs["pixels"]]
            return obs, info

        def step(self, action):
            out = self.env.step(action)
            self.pixels.append(out[0]["pixels"])
            return out

    return PixelRecorder


def _PixelRecorder(env):  # noqa: N802 - a factory standing for a class (gymnasium imported lazily)
    return _pixel_recorder_cls()(env)


def slot_seed(base_seed: int, num_episodes: int, slot: int, retry: int) -> int:
    """Seed of episode slot ``slot`` on its ``retry``-th attempt (disjoint across slots and retries)."""
    return base_seed + slot + num_episodes * retry


def _episode_frames(ep, pixels, cameras) -> list[dict]:
    T = ep.num_frames
    frames = []
    for i in range(T):
        last = i == T - 1
        frame = {
            "observation.state": ep.states[i].astype(np.float32),
            "observation.environment_state": ep.object_positions[i].astype(np.float32),
            "action": ep.actions[i].astype(np.float32),
            "next.done": np.array([last]),
            "next.success": np.array([last and ep.success]),
            "phase.index": np.array([ep.phases[i]], dtype=np.int64),
            "phase.subtask": np.array([ep.phases[i] // robot.N_PHASES_PER_SUBTASK], dtype=np.int64),
            "episode.seed": np.array([ep.seed], dtype=np.int64),
            "task": robot.TASK,
        }
        for cam in cameras:
            frame[f"observation.images.{cam}"] = pixels[i][cam]
        frames.append(frame)
    return frames


def build_shard(job: dict, progress=None) -> dict:
    """Simulate slots [job.start, job.stop) and write them as one finalized LeRobotDataset (a shard).

    Written into ``<name>.tmp`` and renamed to ``<name>`` when complete, so a shard folder without the
    suffix is always whole. ``progress(kind)`` is called with "episode" or "failure".
    """
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from lerobot_pnp.expert import failure_cause, run_expert_episode

    _quiet_libraries()
    final = Path(job["dir"])
    tmp = final.with_name(final.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    cameras = job["env_kwargs"]["cameras"]
    keyframe = job["env_kwargs"]["control_mode"] == "keyframe"
    env = _get_env(job["env_kwargs"])
    ds = LeRobotDataset.create(
        repo_id=f"{job['repo_id']}_shard{job['index']:05d}",
        fps=job["env_kwargs"]["fps"],
        features=dataset_features(job["env_kwargs"]["control_mode"], cameras, job["env_kwargs"]["image_size"]),
        root=tmp,
        robot_type=ROBOT_TYPE,
        use_videos=bool(cameras),
        video_backend="pyav",
        metadata_buffer_size=max(10, job["stop"] - job["start"]),
    )
    seeds, failures = [], []
    sim_s = write_s = 0.0
    for slot in range(job["start"], job["stop"]):
        for retry in range(job["max_retries"] + 1):
            seed = slot_seed(job["seed"], job["num_episodes"], slot, retry)
            t0 = time.perf_counter()
            try:
                ep = run_expert_episode(env, seed)
                if keyframe and ep.num_frames != robot.N_KEYFRAMES:
                    raise ExpertFailure(f"seed {seed}: expert failed: short_episode ({ep.num_frames} frames)")
            except (UnreachableError, ExpertFailure) as err:
                sim_s += time.perf_counter() - t0
                failures.append({"slot": slot, "seed": seed, "cause": failure_cause(err), "message": str(err)})
                if progress:
                    progress("failure")
                continue
            sim_s += time.perf_counter() - t0
            break
        else:
            raise DatasetError(
                f"episode slot {slot}: the expert failed on {job['max_retries'] + 1} seeds in a row "
                f"(last: {failures[-1]['message']}); check the task configuration"
            )
        t0 = time.perf_counter()
        pixels = env.pixels if cameras else None
        if cameras and len(pixels) != ep.num_frames:
            raise DatasetError(f"seed {seed}: {len(pixels)} camera frames for {ep.num_frames} states (bug)")
        for frame in _episode_frames(ep, pixels, cameras):
            ds.add_frame(frame)
        ds.save_episode()
        write_s += time.perf_counter() - t0
        seeds.append(seed)
        if progress:
            progress("episode")
    t0 = time.perf_counter()
    ds.finalize()
    write_s += time.perf_counter() - t0
    record = {
        "index": job["index"],
        "start": job["start"],
        "stop": job["stop"],
        "seeds": seeds,
        "failures": failures,
        "sim_s": sim_s,
        "write_s": write_s,
    }
    (tmp / SHARD_FILE).write_text(json.dumps(record, indent=1))
    if progress:
        progress("shard")
    os.replace(tmp, final)
    return record


# worker-process plumbing
_PROGRESS_QUEUE = None
_PARENT_PID = None


def _worker_init(progress_queue) -> None:
    global _PROGRESS_QUEUE, _PARENT_PID
    _PROGRESS_QUEUE = progress_queue
    _PARENT_PID = os.getppid()
    _single_thread()
    _quiet_libraries()


def _worker_progress(kind: str) -> None:
    # A worker whose parent was killed (kill -9) stops at once, before it could finish (rename) its shard
    # while a resumed run rebuilds the same shard.
    if os.getppid() != _PARENT_PID:
        os._exit(1)
    _PROGRESS_QUEUE.put(kind)


def _worker_build_shard(job: dict) -> dict:
    return build_shard(job, progress=_worker_progress)


# ---------------------------------------------------------------------------------------------- generate
def _manifest(cfg: GenerateConfig) -> dict:
    d = asdict(cfg)
    return {k: d[k] for k in _CONTENT_FIELDS}


def _check_overwritable(root: Path) -> None:
    """Refuse to delete a folder that is neither a dataset, nor our work folder, nor empty."""
    if root.is_file():
        raise DatasetError(f"{root} is a file, not a dataset folder")
    entries = {p.name for p in root.iterdir()}
    if not entries or (root / "meta" / "info.json").is_file() or WORK_DIR in entries:
        return
    raise DatasetError(
        f"refusing to --overwrite {root}: it does not look like a LeRobot dataset (no meta/info.json); "
        "delete it yourself or pick another --root"
    )


def _resolve_shard_size(cfg: GenerateConfig, workers: int) -> int:
    if cfg.shard_size:
        return cfg.shard_size
    kind = "cameras" if cfg.cameras else cfg.representation
    return max(1, min(DEFAULT_SHARD_SIZE[kind], math.ceil(cfg.num_episodes / max(1, workers))))


def generate(cfg: GenerateConfig) -> dict:
    """Generate ``cfg.num_episodes`` successful expert episodes into ``cfg.output_root``; return a summary."""
    t_start = time.perf_counter()
    root = cfg.output_root.resolve()
    workers = cfg.workers or (os.cpu_count() or 1)
    work = root / WORK_DIR

    # 1. What is on disk, and are we allowed to touch it?
    if root.exists():
        if cfg.overwrite:
            _check_overwritable(root)
            shutil.rmtree(root)
        elif not cfg.resume:
            state = (
                "an interrupted generation"
                if work.exists()
                else "a dataset"
                if (root / "meta" / "info.json").exists()
                else "not a dataset"
            )
            raise DatasetError(
                f"{root} already exists ({state}); pass --resume to finish/keep it or --overwrite to replace it"
            )
    if (root / TRASH_DIR).exists():  # killed while deleting the work folder of a finished run
        shutil.rmtree(root / TRASH_DIR)
    if root.exists() and not work.exists():
        # --resume on a finished dataset: verify it matches and report.
        info = validate_dataset(root)
        gen = _read_json(root / GENERATION_FILE, "generation record")
        _check_manifest(gen.get("config", {}), cfg)
        return {
            "root": str(root),
            "status": "already complete",
            "episodes": info["total_episodes"],
            "frames": info["total_frames"],
            "splits": info.get("splits"),
        }

    # 2. The work folder and its manifest (a resumed run must have the same content settings).
    work.mkdir(parents=True, exist_ok=True)
    lock = _lock(work)
    try:
        return _generate_locked(cfg, root, work, workers, t_start)
    finally:
        lock.close()


def _lock(work: Path):
    """An exclusive lock on the work folder: two generators never write the same root at once."""
    import fcntl

    handle = open(work / "lock", "w")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.close()
        raise DatasetError(f"another `lerobot-pnp generate` is writing {work.parent}") from None
    return handle


def _generate_locked(cfg: GenerateConfig, root: Path, work: Path, workers: int, t_start: float) -> dict:
    shards_dir = work / "shards"
    manifest_path = work / "manifest.json"
    if manifest_path.exists():
        manifest = _read_json(manifest_path, "work manifest")
        cfg_shard = manifest.get("shard_size", 0)
        cfg = _with(cfg, shard_size=cfg_shard)
        _check_manifest(manifest, cfg)
        # Leftovers of an interrupted final move: everything except the work folder is redone.
        for entry in root.iterdir():
            if entry.name != WORK_DIR:
                shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
    else:
        # Fresh, or killed before the manifest was written (nothing useful in it).
        if shards_dir.exists():
            shutil.rmtree(shards_dir)
        cfg = _with(cfg, shard_size=_resolve_shard_size(cfg, workers))
        shards_dir.mkdir(parents=True)
        _write_json_atomic(manifest_path, _manifest(cfg))

    # 3. Shards: keep the finished ones, (re)build the rest.
    n, size = cfg.num_episodes, cfg.shard_size
    jobs = []
    for k in range(math.ceil(n / size)):
        jobs.append(
            {
                "index": k,
                "start": k * size,
                "stop": min(n, (k + 1) * size),
                "seed": cfg.seed,
                "num_episodes": n,
                "max_retries": cfg.max_retries,
                "repo_id": cfg.repo_id,
                "env_kwargs": cfg.env_kwargs(),
                "dir": str(shards_dir / f"shard-{k:05d}"),
            }
        )
    for p in shards_dir.glob("*.tmp"):
        shutil.rmtree(p)
    records = {}
    todo = []
    for job in jobs:
        rec_path = Path(job["dir"]) / SHARD_FILE
        if rec_path.is_file():
            records[job["index"]] = _read_json(rec_path, "shard record")
        else:
            if Path(job["dir"]).exists():
                shutil.rmtree(job["dir"])
            todo.append(job)
    done_before = sum(len(r["seeds"]) for r in records.values())
    t_sim = time.perf_counter()
    records.update(_run_jobs(todo, workers, cfg, initial=done_before))
    sim_wall = time.perf_counter() - t_sim

    # 4. Merge, verify, commit.
    t_merge = time.perf_counter()
    ordered = [records[j["index"]] for j in jobs]
    summary = _merge_and_commit(cfg, root, jobs, ordered)
    merge_wall = time.perf_counter() - t_merge
    failures = [f for r in ordered for f in r["failures"]]
    causes: dict[str, int] = {}
    for f in failures:
        causes[f["cause"]] = causes.get(f["cause"], 0) + 1
    summary.update(
        {
            "status": "resumed" if done_before else "generated",
            "episodes_reused": done_before,
            "expert_failures": len(failures),
            "failure_causes": causes,
            "workers": min(workers, max(1, len(todo))),
            "wall_s": round(time.perf_counter() - t_start, 2),
            "generate_wall_s": round(sim_wall, 2),
            "merge_wall_s": round(merge_wall, 2),
            "episodes_per_s": round((n - done_before) / sim_wall, 2) if sim_wall > 0 and n > done_before else None,
            "simulate_cpu_s": round(sum(r["sim_s"] for r in ordered), 2),
            "write_cpu_s": round(sum(r["write_s"] for r in ordered), 2),
        }
    )
    return summary


def _with(cfg: GenerateConfig, **changes) -> GenerateConfig:
    d = asdict(cfg)
    d.update(changes)
    return GenerateConfig(**d)


def _check_manifest(manifest: dict, cfg: GenerateConfig) -> None:
    mine = _manifest(cfg)
    diff = {
        k: (manifest.get(k), mine[k])
        for k in _CONTENT_FIELDS
        if k != "shard_size" and _norm(manifest.get(k)) != _norm(mine[k])
    }
    if diff:
        details = ", ".join(f"{k}: on disk {a!r} vs requested {b!r}" for k, (a, b) in diff.items())
        raise ConfigError(
            f"--resume with different settings than the run on disk ({details}); use the same settings or --overwrite"
        )


def _norm(v):
    return list(v) if isinstance(v, tuple | list) else v


def _run_jobs(todo: list[dict], workers: int, cfg: GenerateConfig, initial: int) -> dict:
    from tqdm import tqdm

    records = {}
    bar = tqdm(
        total=cfg.num_episodes,
        initial=initial,
        desc="episodes",
        unit="ep",
        disable=not cfg.progress,
        dynamic_ncols=True,
        smoothing=0.05,
    )
    fails = [0]

    def tick(kind: str) -> None:
        if kind == "episode":
            bar.update(1)
        elif kind == "failure":
            fails[0] += 1
            bar.set_postfix(failed=fails[0], refresh=False)

    try:
        if workers <= 1 or len(todo) <= 1:
            for job in todo:
                records[job["index"]] = build_shard(job, progress=tick)
        else:
            import multiprocessing as mp

            ctx = mp.get_context("spawn")
            progress_q = ctx.Queue()
            saved = {v: os.environ.get(v) for v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
            for v in saved:
                os.environ[v] = "1"  # inherited by the spawned workers before numpy/torch load
            try:
                with ctx.Pool(min(workers, len(todo)), initializer=_worker_init, initargs=(progress_q,)) as pool:
                    pending = [pool.apply_async(_worker_build_shard, (job,)) for job in todo]
                    while pending:
                        try:
                            while True:
                                tick(progress_q.get(timeout=0.1))
                        except queue.Empty:
                            pass
                        still = []
                        for res in pending:
                            if res.ready():
                                rec = res.get()  # re-raises a worker's exception here
                                records[rec["index"]] = rec
                            else:
                                still.append(res)
                        pending = still
                    pool.close()  # let the workers exit normally (terminate() leaks their semaphores)
                    pool.join()
                    try:
                        while True:
                            tick(progress_q.get_nowait())
                    except queue.Empty:
                        pass
            finally:
                progress_q.close()
                progress_q.join_thread()
                for v, old in saved.items():
                    if old is None:
                        os.environ.pop(v, None)
                    else:
                        os.environ[v] = old
    finally:
        bar.close()
    return records


def _merge_and_commit(cfg: GenerateConfig, root: Path, jobs: list[dict], records: list[dict]) -> dict:
    from lerobot.datasets.aggregate import aggregate_datasets
    from lerobot.datasets.io_utils import load_info, write_info

    _quiet_libraries()
    work = root / WORK_DIR
    merged = work / "merged"
    if merged.exists():
        shutil.rmtree(merged)
    seeds = [s for r in records for s in r["seeds"]]
    if len(seeds) != cfg.num_episodes or len(set(seeds)) != len(seeds):
        raise DatasetError(
            f"shards hold {len(seeds)} episodes ({len(set(seeds))} distinct seeds), "
            f"expected {cfg.num_episodes} distinct; rerun with --overwrite"
        )
    shard_roots = [Path(j["dir"]) for j in jobs]
    if len(shard_roots) == 1:
        shutil.copytree(shard_roots[0], merged, ignore=shutil.ignore_patterns(SHARD_FILE))
    else:
        aggregate_datasets(
            repo_ids=[f"{cfg.repo_id}_shard{j['index']:05d}" for j in jobs],
            aggr_repo_id=cfg.repo_id,
            roots=shard_roots,
            aggr_root=merged,
            concatenate_data=False,  # one data file per shard: a linear-time merge (no rewrites)
        )
    # The split (LeRobot's "start:end" format) and the record of how the data was made.
    info = load_info(merged)
    n = cfg.num_episodes
    n_train = min(n, max(1, round(cfg.train_fraction * n)))
    if cfg.train_fraction < 1 and n >= 2:
        n_train = min(n_train, n - 1)  # a test split is never empty when one was asked for
    info.splits = {"train": f"0:{n_train}"}
    if n_train < n:
        info.splits["test"] = f"{n_train}:{n}"
    write_info(info, merged)
    check = verify_dataset(merged, expected_seeds=seeds)
    generation = {
        "config": _manifest(cfg),
        "env": cfg.env_kwargs(),
        "task": robot.TASK,
        "seed_rule": "slot i, retry r -> seed + i + num_episodes * r",
        "failures": [f for r in records for f in r["failures"]],
        "lerobot_pnp_version": _version(),
    }
    _write_json_atomic(merged / GENERATION_FILE, generation)
    # Commit: move the merged dataset into root, then drop the work folder (atomically renamed first).
    for entry in merged.iterdir():
        os.replace(entry, root / entry.name)
    os.replace(work, root / TRASH_DIR)
    shutil.rmtree(root / TRASH_DIR)
    return {
        "root": str(root),
        "repo_id": cfg.repo_id,
        "representation": cfg.representation,
        "fps": cfg.fps,
        "episodes": check["total_episodes"],
        "frames": check["total_frames"],
        "splits": info.splits,
        "shards": len(jobs),
    }


def _version() -> str:
    from lerobot_pnp import __version__

    return __version__


# ---------------------------------------------------------------------------------------------- checks
def _read_json(path: Path, what: str) -> dict:
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise DatasetError(f"{what} missing: {path}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise DatasetError(f"{what} is corrupt ({path}): {err}") from None


def _write_json_atomic(path: Path, data: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, default=str))
    os.replace(tmp, path)


def _read_parquet(path: Path, what: str):
    import pyarrow.parquet as pq

    try:
        return pq.read_table(path)
    except FileNotFoundError:
        raise DatasetError(f"{what} missing: {path}") from None
    except Exception as err:  # pyarrow raises ArrowInvalid / OSError on truncated or garbage files
        raise DatasetError(f"{what} is corrupt or truncated ({path}): {err}") from None


def validate_dataset(root: str | Path) -> dict:
    """Check that ``root`` holds a complete, readable LeRobot v3.0 dataset; return its info dict.

    Raises DatasetError naming what is wrong (interrupted generation, missing or corrupt metadata,
    unreadable/truncated parquet files, counts that disagree, missing videos). Reads only.
    """
    root = Path(root)
    if not root.is_dir():
        raise DatasetError(f"no dataset at {root}")
    if (root / WORK_DIR).exists():
        raise DatasetError(
            f"{root} holds an interrupted generation (found {WORK_DIR}/); finish it with "
            "`lerobot-pnp generate ... --resume` or start over with --overwrite"
        )
    info = _read_json(root / "meta" / "info.json", "meta/info.json")
    for key in ("codebase_version", "total_episodes", "total_frames", "features", "data_path"):
        if key not in info:
            raise DatasetError(f"meta/info.json in {root} is incomplete: no {key!r}")
    if info["codebase_version"] != "v3.0":
        raise DatasetError(f"{root} is a LeRobot {info['codebase_version']} dataset, expected v3.0")
    _read_json(root / "meta" / "stats.json", "meta/stats.json")
    _read_parquet(root / "meta" / "tasks.parquet", "meta/tasks.parquet")
    ep_files = sorted((root / "meta" / "episodes").glob("chunk-*/file-*.parquet"))
    if not ep_files:
        raise DatasetError(f"no episode metadata in {root}/meta/episodes (dataset not finalized?)")
    import pyarrow as pa

    episodes = pa.concat_tables([_read_parquet(p, "episode metadata") for p in ep_files])
    ep_index = np.sort(episodes.column("episode_index").to_numpy())
    if len(ep_index) != info["total_episodes"] or not np.array_equal(ep_index, np.arange(len(ep_index))):
        raise DatasetError(
            f"{root}: episode metadata lists {len(ep_index)} episodes, info.json says "
            f"{info['total_episodes']} (dataset not finalized or corrupt)"
        )
    data_files = sorted((root / "data").glob("chunk-*/file-*.parquet"))
    if not data_files:
        raise DatasetError(f"no data files in {root}/data")
    frames = sum(_read_parquet(p, "data file").num_rows for p in data_files)
    if frames != info["total_frames"]:
        raise DatasetError(f"{root}: data files hold {frames} frames, info.json says {info['total_frames']}")
    for key, ft in info["features"].items():
        if ft.get("dtype") == "video":
            if not list((root / "videos" / key).glob("chunk-*/file-*.mp4")):
                raise DatasetError(f"{root}: no video files for {key}")
    return info


def open_local_dataset(repo_id: str, root: str | Path | None):
    """Open a dataset with LeRobot's loader (PyAV video backend, no torchcodec probe).

    With a local ``root`` the folder is validated first, so a missing, interrupted or corrupt dataset is a
    clear DatasetError instead of LeRobot falling back to downloading ``repo_id`` from the Hub.
    """
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    if root is not None:
        validate_dataset(root)
    return LeRobotDataset(repo_id, root=root, video_backend="pyav")


def _data_table(root: Path):
    import pyarrow as pa

    files = sorted((Path(root) / "data").glob("chunk-*/file-*.parquet"))
    return pa.concat_tables([_read_parquet(p, "data file") for p in files]).sort_by("index")


# LeRobot's aggregate_stats merges these bookkeeping columns' stats without the per-shard offsets (they are
# never normalised or fed to a policy), so they are not compared.
_INDEX_COLUMNS = ("index", "episode_index", "task_index")


def verify_dataset(root: str | Path, expected_seeds: list[int] | None = None, rtol: float = 1e-3) -> dict:
    """validate_dataset + content checks: distinct episode seeds (in order, if given) and meta/stats.json
    (mean/std/min/max/count of every numeric feature) equal to the statistics recomputed from the data.

    ``rtol``: LeRobot combines per-episode float32 statistics, so a std over thousands of dense frames can
    differ from the float64 recomputation by ~2e-4 relative; a lost or duplicated episode shows in the
    count and seed checks, which are exact."""
    root = Path(root)
    info = validate_dataset(root)
    table = _data_table(root)
    ep = table.column("episode_index").to_numpy()
    seeds = table.column("episode.seed").to_numpy()
    first = np.r_[True, ep[1:] != ep[:-1]]
    ep_seeds = seeds[first]
    if len(ep_seeds) != info["total_episodes"] or len(set(ep_seeds.tolist())) != len(ep_seeds):
        raise DatasetError(f"{root}: {len(ep_seeds)} episodes but {len(set(ep_seeds.tolist()))} distinct seeds")
    if expected_seeds is not None and ep_seeds.tolist() != list(expected_seeds):
        raise DatasetError(f"{root}: episode seeds differ from the generation record")
    stats = _read_json(root / "meta" / "stats.json", "meta/stats.json")
    for key, ft in info["features"].items():
        if ft["dtype"] not in ("float32", "float64", "int64", "bool") or key not in stats or key in _INDEX_COLUMNS:
            continue
        col = table.column(key).to_numpy() if ft["shape"] == [1] else np.stack(table.column(key).to_numpy(False))
        x = np.asarray(col, dtype=np.float64).reshape(len(table), -1)
        s = stats[key]
        expect = {"min": x.min(0), "max": x.max(0), "mean": x.mean(0), "std": x.std(0)}
        for stat, value in expect.items():
            got = np.asarray(s[stat], dtype=np.float64).reshape(-1)
            if not np.allclose(got, value, rtol=rtol, atol=1e-5):
                raise DatasetError(
                    f"{root}: meta/stats.json {key}.{stat} = {got.tolist()} but the data give {value.tolist()}"
                )
        if int(np.asarray(s["count"]).reshape(-1)[0]) != len(table):
            raise DatasetError(f"{root}: meta/stats.json {key}.count != {len(table)} frames")
    return info


def load_split(root: str | Path) -> dict[str, list[int]]:
    """Episode indices of each split stored in ``meta/info.json`` ("splits": {"train": "0:1120", ...})."""
    info = _read_json(Path(root) / "meta" / "info.json", "meta/info.json")
    splits = info.get("splits") or {}
    out = {}
    for name, spec in splits.items():
        try:
            start, stop = (int(v) for v in str(spec).split(":"))
        except ValueError:
            raise DatasetError(f"meta/info.json split {name!r} = {spec!r} is not 'start:end'") from None
        out[name] = list(range(start, stop))
    return out


def data_hash(root: str | Path) -> str:
    """SHA-256 of the data table content (all columns, in frame order), independent of file layout."""
    table = _data_table(Path(root))
    h = hashlib.sha256()
    for name in sorted(table.column_names):
        h.update(name.encode())
        col = table.column(name)
        if col.type.num_fields == 0 and not str(col.type).startswith(("list", "fixed_size_list", "string")):
            h.update(np.ascontiguousarray(col.to_numpy()).tobytes())
        else:
            h.update(json.dumps(col.to_pylist()).encode())
    return h.hexdigest()


# ---------------------------------------------------------------------------------------------- push
def push(cfg: PushConfig) -> dict:
    """Upload ``cfg.output_root`` to the Hub with LeRobot's ``push_to_hub`` (tags ``v3.0``).

    Fails fast, before anything is read for upload, when there is no token or the Hub cannot be reached.
    Never modifies the local folder.
    """
    import socket
    from urllib.parse import urlparse

    root = cfg.output_root.resolve()
    ds = open_local_dataset(cfg.repo_id, root)  # validates the folder first
    from huggingface_hub import constants, get_token

    if constants.HF_HUB_OFFLINE:
        raise DatasetError("cannot push: HF_HUB_OFFLINE is set (unset it to upload)")
    if not get_token():
        raise DatasetError("cannot push: no Hugging Face token found; run `hf auth login` or set HF_TOKEN")
    url = urlparse(constants.ENDPOINT)
    host, port = url.hostname, url.port or (443 if url.scheme == "https" else 80)
    try:
        with socket.create_connection((host, port), timeout=cfg.connect_timeout_s):
            pass
    except OSError as err:
        raise DatasetError(f"cannot push: the Hub at {constants.ENDPOINT} is unreachable ({err})") from None
    try:
        ds.push_to_hub(branch=cfg.branch, private=cfg.private, push_videos=cfg.push_videos)
    except Exception as err:
        raise DatasetError(f"push to {cfg.repo_id} failed: {err}") from err
    return {
        "repo_id": cfg.repo_id,
        "root": str(root),
        "url": f"{constants.ENDPOINT}/datasets/{cfg.repo_id}",
        "tag": "v3.0",
    }
