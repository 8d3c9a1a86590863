"""The study as stages, each cached on disk and reused when finished (an interrupted run resumes).

Stages: 1. dataset (the expert's demonstrations; 1b. the same demonstrations recorded again for a method
that needs another view of them: at the control rate for ACT, with the phase observed for the phase-told
control; checked to be the same episodes) -> 2-3. per method x training seed: train, then evaluate every
suite (same eval seeds for every method), in a process pool the training and each suite's evaluation as jobs
of their own, a suite's starting once its training is done -> 4. report
(``report.md``, figures, ``summary.json``). Every stage is keyed by what determines it (``stages.py``,
``methods.train_stage``; ``lerobot_pnp.cache``): a dataset by its generation settings, a training by its
method, data key, seed and epochs, an evaluation by the training's key, the suite as defined now, its
episodes and seeds, and the episode rule when one chooses its count (``config.EpisodeRule``; a fixed-n
record is then reused cut to where the rule stops, when exact); the key is stored in its JSON, written
atomically. Rerunning the same command only does what is missing; a changed flag re-runs what depends on it, so the report states the config of its results.
The output folder is locked for the run; ``--fresh`` deletes only the entries of its manifest.

The config and its presets: ``report.config``; every path under the output folder: ``report.layout``.
"""

from __future__ import annotations

import json
import os
import time
from contextlib import ExitStack
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from lerobot_pnp.cache import MANIFEST_FILE, STAGE_FILE, Manifest, Stage, code_versions, lock_output, remove
from lerobot_pnp.env_config import BaxterPnPEnvConfig
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.records import records_from_json, records_to_json
from lerobot_pnp.evaluation.suites import get_suites
from lerobot_pnp.recorded_task import read_recorded
from lerobot_pnp.report import adapters, coverage
from lerobot_pnp.report.adapters import check_same_demonstrations
from lerobot_pnp.report.config import StudyConfig, SuiteSpec
from lerobot_pnp.report.layout import StudyLayout
from lerobot_pnp.report.methods import DATA_EFFICIENCY_METHODS, TrainContext, get_methods, keyed_train, train_stage
from lerobot_pnp.report.provenance import command, machine
from lerobot_pnp.report.stages import (
    EVAL_BATCH_SIZE_BEFORE,
    dataset_stage,
    episode_rule,
    eval_stage,
    truncated_record,
    written_by_the_study,
)

# The recordings a method can train on besides the keyframe dataset (``Method.data``): what they are and the
# env-config changes they are generated with (the same seeds, so the same demonstrations).
RECORDINGS: dict[str, tuple[str, dict]] = {
    "dense": ("at the control rate (ACT)", {"control_mode": "dense"}),
    "phase": ("with the phase one-hot observed (the phase-told control)", {"observe_phase": True}),
}


# ---------------------------------------------------------------------------------------------------- helpers
def _write_json(path: Path, data) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=str))
    tmp.replace(path)


def _stage(text: str) -> None:
    print(f"\n=== {text} ===", flush=True)


# ---------------------------------------------------------------------------------------------------- stages
def run_study(cfg: StudyConfig) -> dict:
    """Run every stage that is not finished yet; return a short summary (the report path and headline).

    The studies of ``cfg.alongside`` (config files) run in the same process pool: every study's datasets
    first, then all their trainings and evaluations side by side, then each study's cross-check and report
    (``make demo``: the recovery headline beside the paper's study; the summary is the first study's, the others'
    under ``"alongside"``). Each output folder is locked for the whole run (a second study on it fails at
    once); the top-level entries a study writes are listed in its manifest, so ``--fresh`` deletes only those."""
    cfgs = [cfg, *(load_study_config(path) for path in cfg.alongside)]
    for c in cfgs[1:]:  # how to run (not what to run) is the command line's, for every study
        c.fresh, c.report_only = c.fresh or cfg.fresh, c.report_only or cfg.report_only
    outs = [Path(c.output_dir).resolve() for c in cfgs]
    if len(set(outs)) < len(outs):
        raise ConfigError(f"alongside: two studies write to the same output_dir ({[c.output_dir for c in cfgs]})")
    with ExitStack() as stack:
        for c in cfgs:  # every folder locked before any is cleared or written: a held one stops the run at once
            stack.enter_context(lock_output(Path(c.output_dir), "lerobot-pnp report/demo"))
        manifests = [_manifest(Path(c.output_dir), c.fresh) for c in cfgs]  # every one read and checked first
        for c, manifest in zip(cfgs, manifests, strict=True):
            if c.fresh:
                manifest.clear()
        runs = [_prepare(c, StudyLayout(Path(c.output_dir)), m) for c, m in zip(cfgs, manifests, strict=True)]
        summaries = _run_prepared(runs)
    return summaries[0] if len(summaries) == 1 else {**summaries[0], "alongside": summaries[1:]}


def _manifest(out: Path, fresh: bool) -> Manifest:
    """The study's manifest of ``out`` (refused in one line when it is not one), with what a study folder
    written before manifests provably holds of the study's claimed into it; with ``fresh``, a folder holding
    anything else is refused here, before any folder of the run is cleared."""
    manifest = Manifest(out, "lerobot-pnp report/demo")
    if not manifest.path.exists() and StudyLayout(out).config.is_file():
        manifest.claim(*(p.name for p in out.iterdir() if written_by_the_study(p)))  # an older study
    if fresh and (foreign := manifest.foreign()):
        manifest.refuse_fresh(foreign)
    return manifest


def load_study_config(path: str) -> StudyConfig:
    """A study's config file (``alongside``); one that names studies alongside itself is refused (one level)."""
    import draccus

    from lerobot_pnp.errors import one_line

    if not Path(path).is_file():
        raise ConfigError(f"alongside: {path!r}: no such config file")
    try:
        cfg = draccus.parse(StudyConfig, config_path=path, args=[])
    except ConfigError:
        raise
    except Exception as err:  # a malformed file or an unknown field
        raise ConfigError(f"alongside: {path!r} is not a study config ({one_line(err)})") from err
    if cfg.alongside:
        raise ConfigError(f"alongside: {path!r} names studies alongside itself; list them all in the first config")
    return cfg


@dataclass
class _PreparedStudy:
    """A study whose datasets are ready: its jobs, and what its jobs and its report need."""

    cfg: StudyConfig
    layout: StudyLayout
    manifest: Manifest
    before: set[str]  # the output folder's entries before the run
    methods: list
    base_env: BaxterPnPEnvConfig
    roots: dict[str, Path]
    keys: dict[str, str]
    generation: dict
    timings: dict[str, float]
    jobs: list[Job]  # one per method x training seed (whole)
    started: float

    @property
    def context(self) -> tuple:
        return self.cfg, self.layout, self.roots, self.base_env, self.keys


def _prepare(cfg: StudyConfig, layout: StudyLayout, manifest: Manifest) -> _PreparedStudy:
    """Stage 1: the study's datasets (made or found), and its jobs."""
    out = layout.out
    before = {p.name for p in out.iterdir()}
    manifest.claim(*layout.stage_names())
    _write_json(layout.config, asdict(cfg))
    timings: dict[str, float] = {}
    started = time.perf_counter()
    methods = get_methods(cfg.methods)

    _stage(f"1/4 dataset: {cfg.num_episodes} expert demonstrations ({out})")
    t = time.perf_counter()
    root = layout.dataset()
    keys: dict[str, str] = {}  # recording -> its dataset's stage key
    generation, keys["keyframe"] = dataset_stage(out, root.name, cfg)
    timings["dataset"] = time.perf_counter() - t
    base_env = BaxterPnPEnvConfig.from_dict(read_recorded(root) or {})
    roots = {"keyframe": root}
    for data in dict.fromkeys(m.data for m in methods if m.data != "keyframe"):
        if data not in RECORDINGS:
            raise ConfigError(f"a method trains on the unknown recording {data!r}; valid: {sorted(RECORDINGS)}")
        what, changes = RECORDINGS[data]
        _stage(f"1b/4 {data} dataset: the same {cfg.num_episodes} demonstrations {what}")
        t = time.perf_counter()
        roots[data] = layout.dataset(data)
        manifest.claim(roots[data].name)
        generation[data], keys[data] = dataset_stage(out, roots[data].name, cfg, changes)
        if not cfg.report_only or generation[data].get("status") == "reused":
            check_same_demonstrations(root, roots[data])
        timings[f"dataset_{data}"] = time.perf_counter() - t
    jobs = [Job(m.name, str(s), None) for m in methods for s in (cfg.train_seeds if m.learned else ["-"])]
    jobs += [Job(m, f"n{n}", n) for n in cfg.data_efficiency for m in DATA_EFFICIENCY_METHODS]
    return _PreparedStudy(cfg, layout, manifest, before, methods, base_env, roots, keys, generation, timings, jobs,
                          started)  # fmt: skip


def _run_prepared(runs: list[_PreparedStudy]) -> list[dict]:
    """Stages 2-3 of every study in one pool, then each study's cross-check and report (stage 4)."""
    jobs = [replace(j, study=i) for i, r in enumerate(runs) for j in r.jobs]
    processes = _job_processes(runs[0].cfg, len(jobs))
    for r in runs:
        _stage(f"2-3/4 train and evaluate: {', '.join(m.name for m in r.methods)} (learned: seeds {r.cfg.train_seeds})")
    print(
        f"evaluation: stock LeRobot eval_policy, in process; the same seeds for every method; {len(jobs)} runs "
        f"(method x training seed{', of every study' if len(runs) > 1 else ''}) in {processes} "
        f"process{'es' if processes > 1 else ''}",
        flush=True,
    )
    if processes > 1:  # a trained method's suites spread over the free processes
        jobs = split_jobs(jobs, {j: job_suites(j, runs[j.study].cfg, runs[j.study].base_env) for j in jobs})
    contexts = tuple(r.context for r in runs)
    finished = dict(_run_jobs(jobs, (contexts,), processes, fn=_study_job))
    return [_finish(r, [j for j in jobs if j.study == i], finished, processes) for i, r in enumerate(runs)]


def _study_job(job: Job, contexts: tuple):
    """``run_job`` in the context of the job's study (a module-level function: the pool pickles it)."""
    return run_job(job, *contexts[job.study])


def _finish(run: _PreparedStudy, jobs: list[Job], finished: dict, processes: int) -> dict:
    """The study's results from its jobs, the `lerobot-eval` cross-check and the report."""
    from lerobot_pnp.report.writer import StudyInputs, write_report

    cfg, layout, timings = run.cfg, run.layout, run.timings
    results: dict[str, dict[str, dict[str, list]]] = {}  # method -> tag -> suite -> records, in job order
    left: list[coverage.LeftOut] = []  # what report_only could not show (coverage)
    for job in jobs:
        records, job_timings, job_left = finished[job]
        timings.update(job_timings)
        left += job_left
        for suite, recs in records.items():
            results.setdefault(job.method, {}).setdefault(job.tag, {})[suite] = recs
    results, left = coverage.withhold(results, left)

    cli_check = _cli_check(cfg, run.methods, results, (layout, run.roots, run.keys), timings)
    timings["run/wall_clock"] = time.perf_counter() - run.started  # this invocation, all processes together
    timings["run/processes"] = processes

    _stage(f"4/4 report ({layout.out})")
    run.manifest.claim(*layout.report_names())
    aliases = coverage.suite_aliases(_suites_for(cfg, None), run.base_env)
    study = StudyInputs(cfg, run.methods, results, run.base_env, run.generation, timings, machine(), command(),
                        cli_check, left, {a: of for a, of in aliases.items() if a != of})  # fmt: skip
    summary = write_report(layout, study)
    run.manifest.claim(*({p.name for p in layout.out.iterdir()} - run.before - {MANIFEST_FILE}))  # what else it wrote
    print(f"\nreport: {layout.report}")
    return summary


TRAIN_TIME = "study_train_time.json"  # in a training folder: how long its training took (reported when reused)


# ``Job.part``: a method x seed's training and every suite in one job (one process), or the training alone
ALL, TRAINING = "*", "training"


@dataclass(frozen=True)
class Job:
    """Work for one trained artefact: a method x training seed (``tag``), or a data-efficiency run.

    ``part``: ``ALL`` trains it (if one of its evaluations needs it) and evaluates every suite; a pool runs it
    as ``TRAINING`` (the training alone, when an evaluation needs it) and one job per suite (its evaluation,
    aliases included), each starting once the training has finished, so that a trained method's suites spread
    over every free process instead of running one after the other on the process that trained it."""

    method: str
    tag: str  # a training seed, "-" (nothing to train) or "n<demos>" (data efficiency)
    n_demos: int | None
    part: str = ALL  # ALL, TRAINING or a suite name
    study: int = 0  # which of the studies run in one pool (``StudyConfig.alongside``)

    @property
    def key(self) -> tuple[str, str, str, int]:
        return self.method, self.tag, self.part, self.study

    def after(self) -> tuple[str, str, str, int] | None:
        """The job that must finish first: a suite's evaluation waits for its training; a training waits for the
        training of the same seed that its method continues (DAgger)."""
        method = get_methods([self.method])[0]
        if self.part not in (ALL, TRAINING):
            return (self.method, self.tag, TRAINING, self.study) if method.learned else None
        if method.continues:
            return method.continues, self.tag, TRAINING if self.part == TRAINING else ALL, self.study
        return None


def split_jobs(jobs: list[Job], suites: dict[Job, list[str]]) -> list[Job]:
    """Each job as its training (learned methods) and one job per suite it evaluates (``suites[job]``, aliases
    left out: they are evaluated with the suite they alias)."""
    learned = {m.name for m in get_methods(list(dict.fromkeys(j.method for j in jobs))) if m.learned}
    out: list[Job] = []
    for job in jobs:
        if job.method in learned:
            out.append(replace(job, part=TRAINING))
        out += [replace(job, part=name) for name in suites[job]]
    return out


def _job_processes(cfg: StudyConfig, n_jobs: int) -> int:
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, min(n_jobs, cfg.workers or cores))


def longest_first(jobs: list[Job]) -> list[Job]:
    """The order a pool takes jobs in: the likely longest first, so that the last job to finish is a short one
    and no core idles while one long job runs on alone (longest-processing-time scheduling). A job's class:
    a dense-control method's (every evaluation episode runs at the control rate, failures to the budget's end),
    then one that another continues (DAgger's and DART's rounds wait on it), then the recovering recipe's
    trainings, then other trainings, then evaluations of untrained methods, then those of trained ones (which
    wait for their training anyway); the given order within a class."""
    methods = {m.name: m for m in get_methods(list(dict.fromkeys(j.method for j in jobs)))}
    continued = {m.continues for m in methods.values() if m.continues}

    def cost_class(job: Job) -> float:
        method = methods[job.method]
        if job.part not in (ALL, TRAINING):
            return 4 if method.learned else 3  # an evaluation of an untrained method can start at once
        if method.data == "dense":
            return 0
        if job.method in continued:
            return 1
        if method.policy_overrides.get("mode") == "recovering":
            return 2  # the recovering recipe: several times a clocked net's training
        return 2.5 if method.learned else 3

    return sorted(jobs, key=cost_class)


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

    names = {j.key for j in jobs}
    done: set[tuple[str, str, str, int]] = set()
    pending, running = longest_first(jobs), {}
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
                done.add(job.key)
                yield job, future.result()


def _context(job: Job, method, cfg: StudyConfig, layout: StudyLayout, roots: dict[str, Path], keys: dict[str, str]):
    seed = int(cfg.train_seeds[0] if not job.tag.isdigit() else job.tag)
    data_root = roots["keyframe"] if method.data == "dense" else roots[method.data]  # ACT reads ctx.dense_root
    budget = (read_recorded(roots["keyframe"]) or {}).get("keyframe_budget")  # the recorded task's
    return TrainContext(data_root, layout.train(method.name, job.tag), seed, cfg.epochs, job.n_demos,
                        roots.get("dense"), cfg.act_steps, dict(keys), budget, dict(cfg.recipe_changes))  # fmt: skip


@dataclass
class _Evaluation:
    """One suite's evaluation of a job (with its aliases) and what is on disk for it."""

    suite: Any
    n_episodes: int
    names: list[str]  # the suite and its aliases (``coverage.suite_aliases``)
    stages: list[Stage]
    rule: Any  # the episode rule, or None: the suite's whole n
    finished: Stage | None  # an alias' record made with these settings
    cut: dict | None  # else a fixed-n record holding exactly what the rule would run

    @property
    def needed(self) -> bool:
        return self.finished is None and self.cut is None


def _evaluations(job: Job, method, ctx: TrainContext, cfg: StudyConfig, layout: StudyLayout, base_env):
    """Every suite the job's method x seed evaluates (aliases folded into the suite they alias)."""
    pairs = _suites_for(cfg, job.n_demos, method)
    aliases = coverage.suite_aliases(pairs, base_env)
    out = []
    for suite, n_episodes in [(s, n) for s, n in pairs if aliases[s.name] == s.name]:
        env_parts = [method.env_config(c, ctx).to_dict() for c in suite.env_configs(base_env)]
        names = [a for a, of in aliases.items() if of == suite.name]  # this suite and its aliases
        rule = episode_rule(cfg, method, suite, job.n_demos)  # None: the suite's whole n
        stages = [eval_stage(layout.eval_record(method.name, job.tag, a), method, ctx, n_episodes, env_parts, cfg,
                             rule) for a in names]  # fmt: skip
        finished = next((st for st in stages if st.changes() == []), None)  # any alias' finished record
        cut = None if rule is None or finished is not None else _first_cut(stages, rule, n_episodes, cfg)
        out.append(_Evaluation(suite, n_episodes, names, stages, rule, finished, cut))
    return out


def job_suites(job: Job, cfg: StudyConfig, base_env) -> list[str]:
    """The suites a job evaluates, aliases left out (``split_jobs``)."""
    (method,) = get_methods([job.method])
    pairs = _suites_for(cfg, job.n_demos, method)
    aliases = coverage.suite_aliases(pairs, base_env)
    return [s.name for s, _ in pairs if aliases[s.name] == s.name]


def _train(method, ctx: TrainContext, job: Job, timings: dict):
    """The job's trained artefact (trained now, or found on disk); its training time into ``timings``."""
    t = time.perf_counter()
    artifact, fresh = keyed_train(method, ctx)
    if fresh:  # trained now, not found from an earlier run
        _write_json(ctx.train_dir / TRAIN_TIME, {"wall_s": time.perf_counter() - t})
        print(f"  trained {method.name} seed {job.tag}: {time.perf_counter() - t:.0f} s", flush=True)
    return artifact


def run_job(job: Job, cfg: StudyConfig, layout: StudyLayout, roots: dict[str, Path], base_env, keys: dict[str, str]):
    """Train ``job`` if one of its evaluations is missing or stale, run those evaluations (``job.part``: all of
    it, the training alone or one suite); return the records per suite, the stage timings and what
    ``report_only`` left out (``coverage.LeftOut``). Suites of the same effective conditions are evaluated once
    (``coverage.suite_aliases``). Everything it finishes is on disk, so an interrupted study resumes."""
    import torch

    torch.set_num_threads(1)
    (method,) = get_methods([job.method])
    ctx = _context(job, method, cfg, layout, roots, keys)
    records, timings, left, artifact = {}, {}, [], None
    evaluations = _evaluations(job, method, ctx, cfg, layout, base_env)
    if job.part == TRAINING:
        if method.learned and not cfg.report_only and any(e.needed for e in evaluations):
            _train(method, ctx, job, timings)
        evaluations = []
    elif job.part != ALL:
        evaluations = [e for e in evaluations if e.suite.name == job.part]
    for ev in evaluations:
        suite, names, stage = ev.suite, ev.names, ev.stages[0] if ev.finished is None else ev.finished
        if ev.cut is not None:  # a fixed-n record holding exactly what this evaluation would run
            data = ev.cut
            print(f"  evaluation {method.name} {job.tag} {suite.name}: reused, the first {len(data['episodes'])} "
                  f"of its {data['truncated_from']} episodes (episodes_rule)", flush=True)  # fmt: skip
        elif stage.done("" if cfg.report_only else f"evaluation {method.name} {job.tag} {suite.name}"):
            data = stage.stored()  # finished earlier, with these settings and this trained artefact
        elif cfg.report_only:
            train = train_stage(method, ctx) if method.learned else None
            left += [coverage.left_out(method.name, job.tag, a, stage, train) for a in names]
            print(f"  evaluation {method.name} {job.tag} {', '.join(names)}: left out ({left[-1].why()})", flush=True)
            continue
        else:
            if artifact is None:
                artifact = _train(method, ctx, job, timings)
            data = _evaluate(method, artifact, ctx, suite, ev.n_episodes, base_env, cfg, ev.rule)
            stage.commit(**data)  # the record and the episodes in one atomic write
            ok = sum(e["success"] for e in data["episodes"])
            print(
                f"  {method.name:<13} {job.tag:>5} {suite.name:<16} {ok}/{len(data['episodes'])} ({data['wall_s']:.0f} s)",
                flush=True,
            )
        timings[f"eval/{method.name}/{job.tag}/{suite.name}"] = data["wall_s"]  # once, not once per alias
        records.update(dict.fromkeys(names, records_from_json(data)))
    if (ctx.train_dir / TRAIN_TIME).is_file():  # the time it took when it was trained (this run or earlier)
        timings[f"train/{method.name}/{job.tag}"] = json.loads((ctx.train_dir / TRAIN_TIME).read_text())["wall_s"]
    return records, timings, left


def _first_cut(stages, rule, n_episodes: int, cfg: StudyConfig) -> dict | None:
    """The first of ``stages`` (a suite and its aliases) whose fixed-n record the rule can reuse, truncated."""
    return next((cut for st in stages if (cut := truncated_record(st, rule, n_episodes, cfg)) is not None), None)


def _evaluate(method, artifact, ctx, suite, n_episodes: int, base_env, cfg: StudyConfig, rule=None) -> dict:
    """One suite (all its parts, consecutive seed blocks from ``cfg.eval_seed``) for one trained method. Under
    an episode ``rule`` (a one-part suite): block after block from the first seed until the rule stops, each
    block whole batches of the fixed run, so its episodes are that run's first ones."""
    t = time.perf_counter()
    records, start, batch = [], cfg.eval_seed, cfg.eval_batch_size
    env_cfgs = [method.env_config(c, ctx) for c in suite.env_configs(base_env)]
    for env_cfg, n in zip(env_cfgs, suite.part_episodes(n_episodes), strict=True):
        done = 0
        for stop in [n] if rule is None else rule.stops(n, batch):
            if stop > done:
                records += method.evaluate(artifact, ctx, env_cfg, stop - done, start + done, batch)
            done = stop
            if rule is not None and rule.stop_at([r.success for r in records], n, batch) is not None:
                break
        start += n
    data = records_to_json(records, time.perf_counter() - t)
    data["env_parts"] = [c.to_dict() for c in env_cfgs]
    return data


def _cli_check(cfg: StudyConfig, methods, results, where: tuple, timings: dict) -> dict | None:
    """The first seeds of the nominal suite through the `lerobot-eval` CLI, compared episode by episode
    (``where``: the output folder, the recordings' roots and keys); re-run when its checkpoint changed."""
    from lerobot_pnp.report.cli_eval import EvalSpec, run_eval

    learned = [m for m in methods if m.learned]
    if not cfg.cli_check_episodes or not learned:
        return None
    if "nominal" not in results.get(learned[0].name, {}).get(tag := str(cfg.train_seeds[0]), {}):
        planned = cfg.report_only and "nominal" in [s.name for s in cfg.suites]
        return {"left_out": f"{learned[0].name} seed {tag} on `nominal` is left out"} if planned else None
    layout, roots, keys = where
    n = min(cfg.cli_check_episodes, len(results[learned[0].name][tag]["nominal"]))
    cli_dir = layout.cli_check
    ctx = _context(Job(learned[0].name, tag, None), learned[0], cfg, layout, roots, keys)
    stage = Stage(cli_dir / STAGE_FILE, {"stage": "cli_check", "train": train_stage(learned[0], ctx).key, "n": n,
                                         "eval_seed": cfg.eval_seed, "eval_batch_size": cfg.eval_batch_size,
                                         "versions": code_versions()}, added=EVAL_BATCH_SIZE_BEFORE)  # fmt: skip
    if not stage.done("lerobot-eval cross-check"):
        if cfg.report_only:  # the report says it was left out, and why
            return {"left_out": coverage.left_out(learned[0].name, tag, "nominal", stage, None).why()}
        remove(cli_dir)
    _stage(f"3b cross-check: {n} nominal episodes of {learned[0].name} seed {tag} through the lerobot-eval CLI")
    t = time.perf_counter()
    cli = run_eval(
        adapters.checkpoint_of(layout.train(learned[0].name, tag)),
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
    split = method is not None and method.learned and n_demos is None  # a cell pooling the training seeds
    pairs = [(s, cfg.seed_episodes(spec.n_episodes) if split else spec.n_episodes)
             for spec in specs for s in get_suites([spec.name])]  # fmt: skip
    if method is not None and method.suites is not None:
        pairs = [(s, n) for s, n in pairs if s.name in method.suites]
    return pairs
