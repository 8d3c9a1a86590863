"""The study as stages, each cached on disk and reused when finished (an interrupted run resumes).

Stages: 1. dataset (the expert's demonstrations; 1b. the same demonstrations recorded again for a method
that needs another view of them: at the control rate for ACT, with the phase observed for the phase-told
control; checked to be the same episodes) -> 2-3. jobs, one per method x training seed: train, then
evaluate every suite (same eval seeds for every method), run side by side in a process pool -> 4. report
(``report.md``, figures, ``summary.json``). Every stage is keyed by what determines it (``stages.py``,
``methods.train_stage``; ``lerobot_pnp.cache``): a dataset by its generation settings, a training by its
method, data key, seed and epochs, an evaluation by the training's key, the suite as defined now, its
episodes and seeds (the key is stored in its JSON, written atomically). Rerunning the same command only does
what is missing; a changed flag re-runs what depends on it, so the report states the config of its results.
The output folder is locked for the run; ``--fresh`` deletes only the entries of its manifest.

Presets (``preset``): ``demo`` (the README's main command, < 15 min on 2 cores), ``quick`` (CI-sized, a few
minutes) and ``full`` (the whole study). Fields left at None take the preset's value.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from lerobot_pnp.cache import MANIFEST_FILE, STAGE_FILE, Manifest, Stage, code_versions, lock_output, remove
from lerobot_pnp.env_config import BaxterPnPEnvConfig, read_recorded
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.records import records_from_json, records_to_json
from lerobot_pnp.evaluation.suites import get_suites
from lerobot_pnp.report import adapters
from lerobot_pnp.report.adapters import check_same_demonstrations
from lerobot_pnp.report.methods import TrainContext, get_methods, keyed_train, train_stage
from lerobot_pnp.report.stages import dataset_stage, eval_stage, written_by_the_study

# The recordings a method can train on besides the keyframe dataset (``Method.data``): what they are and the
# env-config changes they are generated with (the same seeds, so the same demonstrations).
RECORDINGS: dict[str, tuple[str, dict]] = {
    "dense": ("at the control rate (ACT)", {"control_mode": "dense"}),
    "phase": ("with the phase one-hot observed (the phase-told control)", {"observe_phase": True}),
}


@dataclass
class SuiteSpec:
    name: str  # a suite of suites.SUITES, or a sweep group ("nudge")
    n_episodes: int = 200


# Episode counts: the 95 % Wilson half-width is <= 4.4 pts at n = 500, <= 7 pts at n = 200 and <= 10 pts at
# n = 100 (worst case, p = 0.5); near 0 or 100 % it is far smaller (n = 100, 98 %: [93.0, 99.4]). A learned
# method pools 3 training seeds (3 n episodes). The demo's headline gets 500 per seed. The full study gives
# 300 to nominal and 100 to each other suite: enough to separate 50 % from 80 %, or 100 % from 90 %, on the
# paired test. Measured from scratch on 2 cores with two job processes: 63 min (datasets 5 min, then 36
# train-and-evaluate jobs: 55 min of training and 60 min of evaluation, side by side).
PRESETS: dict[str, dict] = {
    "demo": {
        "num_episodes": 1400,
        "epochs": 300,
        "train_seeds": [1000, 1001, 1002],
        "methods": ["expert", "lookup_table", "clocked_lstm"],
        "suites": [SuiteSpec("nominal", 500), SuiteSpec("nudge_0.03", 200)],
        "data_efficiency": [],
        "cli_check_episodes": 50,
    },
    "quick": {
        "num_episodes": 300,
        "epochs": 150,
        "train_seeds": [1000],
        "methods": ["lookup_table", "clocked_lstm"],
        "suites": [SuiteSpec("nominal", 100), SuiteSpec("nudge_0.03", 100)],
        "data_efficiency": [],
        "cli_check_episodes": 0,
    },
    "full": {
        "num_episodes": 1400,
        "epochs": 300,
        "train_seeds": [1000, 1001, 1002],
        # the costliest: act (its dense recording, 3 min once, then ~2 min of training and ~8 min of dense
        # evaluation per seed) and recovering_dagger (~5 min of rollouts and retraining per seed)
        "methods": [
            "expert",
            "lookup_table",
            "clocked_lstm",
            "shared_lstm",
            "memoryless",
            "memoryless_mlp",
            "phase_told_mlp",
            "recovering",
            "recovering_dagger",
            "act",
        ],
        "suites": [
            SuiteSpec("nominal", 300),
            SuiteSpec("slack", 100),
            SuiteSpec("edge_strip", 100),
            SuiteSpec("outside_ring", 100),
            SuiteSpec("nudge", 100),
            SuiteSpec("obs_noise", 100),
            SuiteSpec("latency", 100),
            SuiteSpec("grasp_miss", 100),
            SuiteSpec("drop", 100),
            SuiteSpec("displace", 100),
            SuiteSpec("random_yaw", 100),
            SuiteSpec("random_place", 100),
        ],
        "data_efficiency": [10, 30, 100, 300, 1120],  # 1120 = the whole training split
        "cli_check_episodes": 200,
    },
}


@dataclass
class StudyConfig:
    """``lerobot-pnp demo`` / ``lerobot-pnp report``: the study (see the module doc for the presets)."""

    output_dir: str = "outputs/demo"  # everything the study writes (datasets, checkpoints, report.md); resumable
    preset: str = "demo"  # the study's size: demo (the README's main run), quick (CI-sized) or full (the whole study)
    quick: bool = False  # shorthand for preset=quick
    full: bool = False  # shorthand for preset=full
    num_episodes: int | None = None  # demonstrations generated (80 % train / 20 % held out)
    dataset_seed: int = 0  # seed of the first demonstration (episode i uses dataset_seed + i)
    # processes for generation and for the train-and-evaluate jobs (each single-threaded); 0 = one per core
    workers: int = 0
    epochs: int | None = None  # training epochs of each learned method that trains by epochs
    train_seeds: list[int] | None = None  # one training (and evaluation) per learned method and seed
    methods: list[str] | None = None  # methods compared (methods.METHODS), e.g. '["lookup_table", "clocked_lstm"]'
    # evaluation suites and episodes of each, e.g. '[{"name": "nominal", "n_episodes": 100}]'; a group name: its sweep
    suites: list[SuiteSpec] | None = None
    data_efficiency: list[int] | None = None  # numbers of training demonstrations (clocked LSTM vs lookup)
    # episodes of the nominal suite re-run through the real `lerobot-eval` CLI (first learned method, first
    # seed) to show the in-process evaluation gives the same per-episode successes; 0 = skip
    cli_check_episodes: int | None = None
    eval_seed: int = 100_000  # first evaluation seed (disjoint from the dataset's seeds 0..)
    eval_batch_size: int = 50  # sub-envs of the SyncVectorEnv
    act_steps: int | None = None  # ACT training steps per seed (None = act_baseline.ActBudget's default)
    fresh: bool = False  # delete output_dir first
    report_only: bool = False  # write the report from the finished evaluations only (train/evaluate nothing)

    def __post_init__(self):
        if self.quick and self.full:
            raise ConfigError("pass either --quick or --full, not both")
        self.preset = "quick" if self.quick else "full" if self.full else self.preset
        if self.preset not in PRESETS:
            raise ConfigError(f"preset must be one of {sorted(PRESETS)}, got {self.preset!r}")
        for key, value in PRESETS[self.preset].items():
            if getattr(self, key) is None:
                setattr(self, key, value)
        self.suites = [SuiteSpec(**s) if isinstance(s, dict) else s for s in self.suites]
        if self.num_episodes < 10:
            raise ConfigError(f"num_episodes must be >= 10 for an 80/20 split, got {self.num_episodes}")
        if self.epochs < 1 or not self.train_seeds:
            raise ConfigError("epochs must be >= 1 and train_seeds non-empty")
        if any(s.n_episodes < 1 for s in self.suites):
            raise ConfigError("every suite needs n_episodes >= 1")
        get_methods(self.methods)  # unknown names fail now, not after an hour
        get_suites([s.name for s in self.suites])


# ---------------------------------------------------------------------------------------------------- helpers
def _write_json(path: Path, data) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=str))
    tmp.replace(path)


def machine() -> dict:
    """The machine the study ran on (for the report)."""
    import importlib.metadata as md

    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = {}
    for pkg in ("lerobot", "torch", "mujoco", "gymnasium", "numpy"):
        try:
            versions[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            versions[pkg] = "?"
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu": cpu,
        "cores_available": cores,
        "python": platform.python_version(),
        "os": platform.platform(),
        **versions,
    }


def _stage(text: str) -> None:
    print(f"\n=== {text} ===", flush=True)


# ---------------------------------------------------------------------------------------------------- stages
def run_study(cfg: StudyConfig) -> dict:
    """Run every stage that is not finished yet; return a short summary (the report path and headline).

    The output folder is locked for the whole run (a second study on it fails at once); the top-level
    entries the study writes are listed in its manifest, so ``--fresh`` deletes only those."""
    out = Path(cfg.output_dir)
    with lock_output(out, "lerobot-pnp report/demo"):
        manifest = Manifest(out, "lerobot-pnp report/demo")
        if not manifest.path.exists() and (out / "study_config.json").is_file():
            manifest.claim(*(p.name for p in out.iterdir() if written_by_the_study(p.name)))  # an older study
        if cfg.fresh:
            manifest.clear()
        return _run_locked(cfg, out, manifest)


def _run_locked(cfg: StudyConfig, out: Path, manifest: Manifest) -> dict:
    from lerobot_pnp.report.writer import write_report

    before = {p.name for p in out.iterdir()}
    manifest.claim("study_config.json", "dataset", "train", "evals", "lerobot_eval_cli")
    _write_json(out / "study_config.json", asdict(cfg))
    timings: dict[str, float] = {}
    started = time.perf_counter()
    methods = get_methods(cfg.methods)

    _stage(f"1/4 dataset: {cfg.num_episodes} expert demonstrations")
    t = time.perf_counter()
    root = out / "dataset"
    keys: dict[str, str] = {}  # recording -> its dataset's stage key
    generation, keys["keyframe"] = dataset_stage(out, "dataset", cfg)
    timings["dataset"] = time.perf_counter() - t
    base_env = BaxterPnPEnvConfig.from_dict(read_recorded(root) or {})
    roots = {"keyframe": root}
    for data in dict.fromkeys(m.data for m in methods if m.data != "keyframe"):
        if data not in RECORDINGS:
            raise ConfigError(f"a method trains on the unknown recording {data!r}; valid: {sorted(RECORDINGS)}")
        what, changes = RECORDINGS[data]
        _stage(f"1b/4 {data} dataset: the same {cfg.num_episodes} demonstrations {what}")
        t = time.perf_counter()
        roots[data] = out / f"dataset_{data}"
        manifest.claim(roots[data].name)
        generation[data], keys[data] = dataset_stage(out, roots[data].name, cfg, changes)
        check_same_demonstrations(root, roots[data])
        timings[f"dataset_{data}"] = time.perf_counter() - t

    _stage(f"2-3/4 train and evaluate: {', '.join(m.name for m in methods)} (learned: seeds {cfg.train_seeds})")
    jobs = [Job(m.name, str(s), None) for m in methods for s in (cfg.train_seeds if m.learned else ["-"])]
    jobs += [Job(m, f"n{n}", n) for n in cfg.data_efficiency for m in ("lookup_table", "clocked_lstm")]
    processes = _job_processes(cfg, len(jobs))
    print(
        f"evaluation: stock LeRobot eval_policy, in process; the same seeds for every method; {len(jobs)} jobs "
        f"(method x training seed) in {processes} process{'es' if processes > 1 else ''}",
        flush=True,
    )
    finished = dict(_run_jobs(jobs, (cfg, out, roots, base_env, keys), processes))
    results: dict[str, dict[str, dict[str, list]]] = {}  # method -> tag -> suite -> records, in job order
    for job in jobs:
        records, job_timings = finished[job]
        timings.update(job_timings)
        for suite, recs in records.items():
            results.setdefault(job.method, {}).setdefault(job.tag, {})[suite] = recs

    cli_check = _cli_check(cfg, methods, results, (out, roots, keys), timings)
    timings["run/wall_clock"] = time.perf_counter() - started  # this invocation, all processes together
    timings["run/processes"] = processes

    _stage("4/4 report")
    manifest.claim("report.md", "summary.json", "figures")
    summary = write_report(out, cfg, methods, results, base_env, generation, timings, machine(), _command(), cli_check)
    manifest.claim(*({p.name for p in out.iterdir()} - before - {MANIFEST_FILE}))  # whatever else it wrote
    print(f"\nreport: {out / 'report.md'}")
    return summary


TRAIN_TIME = "study_train_time.json"  # in a training folder: how long its training took (reported when reused)


@dataclass(frozen=True)
class Job:
    """One trained artefact and its evaluations: a method x training seed (``tag``), or a data-efficiency run."""

    method: str
    tag: str  # a training seed, "-" (nothing to train) or "n<demos>" (data efficiency)
    n_demos: int | None

    def after(self) -> tuple[str, str] | None:
        """The job that must finish first: the run of the same seed that this method continues (DAgger)."""
        continues = get_methods([self.method])[0].continues
        return (continues, self.tag) if continues else None


def _job_processes(cfg: StudyConfig, n_jobs: int) -> int:
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, min(n_jobs, cfg.workers or cores))


def _run_jobs(jobs: list[Job], context: tuple, processes: int, fn=None):
    """Yield ``(job, fn(job, *context))`` for every job (``fn``: ``run_job``, a module-level function). One process: in order, in this process. Several: a
    spawned process pool (each job is single-threaded: torch and MuJoCo on one core), a job starting once the
    job it continues has finished; results come in order of completion."""
    fn = fn or run_job
    if processes == 1:
        for job in jobs:
            yield job, fn(job, *context)
        return
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    names = {(j.method, j.tag) for j in jobs}
    done: set[tuple[str, str]] = set()
    pending, running = list(jobs), {}
    from lerobot_pnp.dataset.executors import die_with_parent

    # a worker dies with this process (kill -9 included), as the generation's do: none writes on alone
    pool = ProcessPoolExecutor(
        processes, mp_context=mp.get_context("spawn"), initializer=die_with_parent, initargs=(os.getpid(),)
    )
    with pool:
        while pending or running:
            for job in [j for j in pending if j.after() not in names or j.after() in done]:
                if len(running) >= processes:
                    break
                pending.remove(job)
                running[pool.submit(fn, job, *context)] = job
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in finished:
                job = running.pop(future)
                done.add((job.method, job.tag))
                yield job, future.result()


def _context(job: Job, method, cfg: StudyConfig, out: Path, roots: dict[str, Path], keys: dict[str, str]):
    seed = int(cfg.train_seeds[0] if not job.tag.isdigit() else job.tag)
    data_root = roots["keyframe"] if method.data == "dense" else roots[method.data]  # ACT reads ctx.dense_root
    return TrainContext(data_root, out / "train" / method.name / f"seed{job.tag}", seed, cfg.epochs, job.n_demos,
                        roots.get("dense"), cfg.act_steps, dict(keys))  # fmt: skip


def run_job(job: Job, cfg: StudyConfig, out: Path, roots: dict[str, Path], base_env, keys: dict[str, str]):
    """Train ``job`` if one of its evaluations is missing or stale, run those evaluations; return the records
    per suite and the stage timings. Everything it finishes is on disk, so an interrupted study resumes."""
    import torch

    torch.set_num_threads(1)
    (method,) = get_methods([job.method])
    ctx = _context(job, method, cfg, out, roots, keys)
    records, timings, artifact, trained = {}, {}, None, False
    for suite, n_episodes in _suites_for(cfg, job.n_demos, method):
        path = out / "evals" / method.name / f"seed{job.tag}" / f"{suite.name}.json"
        env_parts = [method.env_config(c, ctx).to_dict() for c in suite.env_configs(base_env)]
        stage = eval_stage(path, method, ctx, suite, n_episodes, env_parts, cfg)
        if stage.done(f"evaluation {method.name} {job.tag} {suite.name}"):
            data = stage.stored()  # finished earlier, with these settings and this trained artefact
        elif cfg.report_only:
            continue
        else:
            if not trained:
                t = time.perf_counter()
                (artifact, fresh), trained = keyed_train(method, ctx), True
                if fresh:  # trained now, not found from an earlier run
                    _write_json(ctx.train_dir / TRAIN_TIME, {"wall_s": time.perf_counter() - t})
                    print(f"  trained {method.name} seed {job.tag}: {time.perf_counter() - t:.0f} s", flush=True)
            data = _evaluate(method, artifact, ctx, suite, n_episodes, base_env, cfg)
            stage.commit(**data)  # the record and the episodes in one atomic write
            ok = sum(e["success"] for e in data["episodes"])
            print(
                f"  {method.name:<13} {job.tag:>5} {suite.name:<16} {ok}/{len(data['episodes'])} ({data['wall_s']:.0f} s)",
                flush=True,
            )
        timings[f"eval/{method.name}/{job.tag}/{suite.name}"] = data["wall_s"]
        records[suite.name] = records_from_json(data)
    if (ctx.train_dir / TRAIN_TIME).is_file():  # the time it took when it was trained (this run or earlier)
        timings[f"train/{method.name}/{job.tag}"] = json.loads((ctx.train_dir / TRAIN_TIME).read_text())["wall_s"]
    return records, timings


def _evaluate(method, artifact, ctx, suite, n_episodes: int, base_env, cfg: StudyConfig) -> dict:
    """One suite (all its parts, consecutive seed blocks from ``cfg.eval_seed``) for one trained method."""
    t = time.perf_counter()
    records, start = [], cfg.eval_seed
    env_cfgs = [method.env_config(c, ctx) for c in suite.env_configs(base_env)]
    for env_cfg, n in zip(env_cfgs, suite.part_episodes(n_episodes), strict=True):
        if n:
            records += method.evaluate(artifact, ctx, env_cfg, n, start, cfg.eval_batch_size)
        start += n
    data = records_to_json(records, time.perf_counter() - t)
    data["env_parts"] = [c.to_dict() for c in env_cfgs]
    return data


def _cli_check(cfg: StudyConfig, methods, results, where: tuple, timings: dict) -> dict | None:
    """The first seeds of the nominal suite through the `lerobot-eval` CLI, compared episode by episode
    (``where``: the output folder, the recordings' roots and keys); re-run when its checkpoint changed."""
    from lerobot_pnp.report.cli_eval import EvalSpec, run_eval

    learned = [m for m in methods if m.learned]
    if (
        not cfg.cli_check_episodes
        or not learned
        or "nominal" not in results.get(learned[0].name, {}).get(tag := str(cfg.train_seeds[0]), {})
    ):
        return None
    out, roots, keys = where
    n = min(cfg.cli_check_episodes, len(results[learned[0].name][tag]["nominal"]))
    cli_dir = out / "lerobot_eval_cli" / "nominal"
    ctx = _context(Job(learned[0].name, tag, None), learned[0], cfg, out, roots, keys)
    stage = Stage(cli_dir / STAGE_FILE, {"stage": "cli_check", "train": train_stage(learned[0], ctx).key, "n": n,
                                         "eval_seed": cfg.eval_seed, "versions": code_versions()})  # fmt: skip
    if not stage.done("lerobot-eval cross-check"):
        if cfg.report_only:
            return None
        remove(cli_dir)
    _stage(f"3b cross-check: {n} nominal episodes of {learned[0].name} seed {tag} through the lerobot-eval CLI")
    t = time.perf_counter()
    cli = run_eval(
        adapters.checkpoint_of(out / "train" / learned[0].name / f"seed{tag}"),
        cli_dir,
        EvalSpec("nominal", n),
        cfg.eval_seed,
        cfg.eval_batch_size,
    )
    stage.commit()
    timings["cli_check"] = time.perf_counter() - t
    ours = {r.seed: r.success for r in results[learned[0].name][tag]["nominal"] if r.seed < cfg.eval_seed + n}
    theirs = cli["per_episode"]
    agree = sum(ours.get(s) == v for s, v in theirs.items())
    return {
        "method": learned[0].name,
        "seed": tag,
        "n": len(theirs),
        "agree": agree,
        "cli_pc_success": cli["pc_success"],
        "in_process_successes": sum(ours.values()),
        "eval_info": cli["eval_info"],
    }


def _suites_for(cfg: StudyConfig, n_demos: int | None, method=None):
    """(suite, episodes) pairs evaluated for a job; data-efficiency runs are evaluated on nominal only, a
    method with a ``suites`` list only on those."""
    specs = [SuiteSpec("nominal", 200)] if n_demos is not None else cfg.suites
    pairs = [(s, spec.n_episodes) for spec in specs for s in get_suites([spec.name])]
    if method is not None and method.suites is not None:
        pairs = [(s, n) for s, n in pairs if s.name in method.suites]
    return pairs


def _command() -> str:
    args = " ".join(sys.argv[1:]) if sys.argv and Path(sys.argv[0]).name.startswith("lerobot-pnp") else ""
    return f"lerobot-pnp {args}".strip() if args else "lerobot_pnp.report.run.run_study (library call)"
