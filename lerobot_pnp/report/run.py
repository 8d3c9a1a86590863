"""The study as stages, each cached on disk and reused when finished (an interrupted run resumes).

Stages: 1. dataset (the expert's demonstrations; 1b. the same demonstrations recorded again for a method that
needs another view of them: at the control rate for ACT, with the phase observed for the phase-told control;
checked to be the same episodes) -> 2-3. per method x training seed: train, then evaluate every suite (same eval
seeds for every method), in a process pool the training and each suite's evaluation as jobs of their own, a
suite's starting once its training is done (the `lerobot-eval` cross-check a job of the pool too) -> 4. report
(``report.md``, figures, ``summary.json``, with what the run cost: ``report.cost``). Every stage is keyed by
what determines it (``stages.py``, ``methods.train_stage``; ``lerobot_pnp.cache``): a dataset by its generation
settings, a training by its method, data key, seed and epochs, an evaluation by the training's key, the suite as
defined now, its episodes and seeds, and the episode rule when one chooses its count (``config.EpisodeRule``; a
fixed-n record is then reused cut to where the rule stops, when exact); the key is stored in its JSON, written
atomically. Rerunning the same command only does what is missing; a changed flag re-runs what depends on it, so
the report states the config of its results. The output folder is locked for the run, and every name the study
writes there is checked before any folder is written or cleared (``report.folder``): the study writes, replaces
and (``--fresh``) deletes only what it wrote.

This module runs the stages in order; the jobs and their pool: ``report.schedule``; what one job does (train,
evaluate): ``report.job``; the same datasets and jobs as SLURM jobs (``--executor slurm``): ``report.cluster``; the `lerobot-eval` cross-check: ``report.cross_check``; the config and its presets:
``report.config``; every path under the output folder: ``report.layout``.
"""

from __future__ import annotations

import time
from contextlib import ExitStack
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.integration.recorded_task import read_recorded
from lerobot_pnp.outputs import OutputFolder
from lerobot_pnp.report import coverage, cross_check
from lerobot_pnp.report.adapters import check_same_demonstrations
from lerobot_pnp.report.config import StudyConfig, SuiteSpec  # noqa: F401  (SuiteSpec: the CLI's and callers')
from lerobot_pnp.report.cost import CostMeter, add_cost
from lerobot_pnp.report.folder import interrupted, open_study_folder, refuse_taken, study_names
from lerobot_pnp.report.job import job_suites, run_job, suites_for
from lerobot_pnp.report.layout import CLUSTER_DIR, StudyLayout
from lerobot_pnp.report.methods import DATA_EFFICIENCY_METHODS, get_methods
from lerobot_pnp.report.provenance import command, machine
from lerobot_pnp.report.schedule import CLI_CHECK, Job, job_processes, run_jobs, split_jobs
from lerobot_pnp.report.stages import dataset_stage
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

# The recordings a method can train on besides the keyframe dataset (``Method.data``): what they are and the
# env-config changes they are generated with (the same seeds, so the same demonstrations).
RECORDINGS: dict[str, tuple[str, dict]] = {
    "dense": ("at the control rate (ACT)", {"control_mode": "dense"}),
    "phase": ("with the phase one-hot observed (the phase-told control)", {"observe_phase": True}),
}


# ---------------------------------------------------------------------------------------------------- helpers
def _stage(text: str) -> None:
    print(f"\n=== {text} ===", flush=True)


# ---------------------------------------------------------------------------------------------------- stages
def run_study(cfg: StudyConfig) -> dict:
    """Run every stage that is not finished yet; return a short summary (the report path and headline).

    The studies of ``cfg.alongside`` (config files) run in the same process pool: every study's datasets
    first, then all their trainings and evaluations side by side, then each study's cross-check and report
    (``make demo``: the recovery headline beside the paper's study; the summary is the first study's, the others'
    under ``"alongside"``). Each output folder is locked for the whole run (a second study on it fails at
    once). Before anything is written or cleared, in any folder: the executor is checked, and every name a
    study writes (``folder.refuse_taken``); ``--fresh`` then deletes only what the study wrote. An interrupted
    run is one line saying how to continue (``folder.interrupted``). What the run cost (wall clock, CPU, memory
    and disk per stage, and whether it did every stage itself) goes into every study's ``summary.json`` as
    ``cost`` (``report.cost``)."""
    cfgs = [cfg, *(load_study_config(path) for path in cfg.alongside)]
    for c in cfgs[1:]:  # how to run (not what to run) is the command line's, for every study
        c.fresh, c.report_only = c.fresh or cfg.fresh, c.report_only or cfg.report_only
        c.executor, c.slurm = cfg.executor, cfg.slurm
    outs = [Path(c.output_dir).resolve() for c in cfgs]
    if len(set(outs)) < len(outs):
        raise ConfigError(f"alongside: two studies write to the same output_dir ({[c.output_dir for c in cfgs]})")
    if cfg.executor == "slurm":  # SLURM missing: refused before any folder is made
        from lerobot_pnp.report.cluster import check_available

        check_available()
    meter = CostMeter(outs)
    try:
        with ExitStack() as stack:
            folders = [stack.enter_context(open_study_folder(Path(c.output_dir))) for c in cfgs]  # all locked first
            runs = _start(cfgs, folders, meter)
            meter.stage("datasets")
            summaries = _run_prepared(runs, meter)
            cost = meter.record()
            for r in runs:
                add_cost(r.layout.summary, cost)
    except KeyboardInterrupt:
        raise interrupted(Path(cfg.output_dir)) from None
    finally:
        meter.sampler.stop()
    return summaries[0] if len(summaries) == 1 else {**summaries[0], "alongside": summaries[1:]}


def _start(cfgs: list[StudyConfig], folders: list[OutputFolder], meter: CostMeter) -> list[_PreparedStudy]:
    """Every study's folder checked (cluster jobs of an earlier run, the names it writes), then cleared
    (``--fresh``), then its datasets made."""
    if any(f.path.joinpath(CLUSTER_DIR).is_dir() for f in folders):  # an earlier run's cluster jobs still at work
        from lerobot_pnp.report.cluster import refuse_live_jobs

        for f in folders:
            refuse_live_jobs(f.path)
    layouts = [StudyLayout(f.path) for f in folders]
    for c, f, layout in zip(cfgs, folders, layouts, strict=True):
        refuse_taken(f, study_names(c, layout))
    for c, f in zip(cfgs, folders, strict=True):
        if c.fresh:
            f.clear()
    runs = [_prepare(c, layout, f) for c, f, layout in zip(cfgs, folders, layouts, strict=True)]
    for r in runs:  # a dataset counts as made by this run only when generated now, from nothing
        made = [r.generation, *(r.generation[data] for data in RECORDINGS if data in r.generation)]
        meter.count("datasets", sum(g.get("status") == "generated" for g in made), len(made))
    return runs


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
    folder: OutputFolder
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


def _prepare(cfg: StudyConfig, layout: StudyLayout, folder: OutputFolder) -> _PreparedStudy:
    """Stage 1: the study's datasets (made or found), and its jobs."""
    out = layout.out
    folder.claim(*layout.stage_names())
    folder.write_json(layout.config.name, asdict(cfg))
    timings: dict[str, float] = {}
    started = time.perf_counter()
    methods = get_methods(cfg.methods)

    _stage(f"1/4 dataset: {cfg.num_episodes} expert demonstrations ({out})")
    t = time.perf_counter()
    root = layout.dataset()
    keys: dict[str, str] = {}  # recording -> its dataset's stage key
    make_dataset = dataset_stage
    if cfg.executor == "slurm":  # each dataset made by a cluster job
        from lerobot_pnp.report.cluster import dataset_on_slurm as make_dataset

        folder.claim(CLUSTER_DIR)
    generation, keys["keyframe"] = make_dataset(out, root.name, cfg)
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
        folder.claim(roots[data].name)
        generation[data], keys[data] = make_dataset(out, roots[data].name, cfg, changes)
        if not cfg.report_only or generation[data].get("status") == "reused":
            check_same_demonstrations(root, roots[data])
        timings[f"dataset_{data}"] = time.perf_counter() - t
    jobs = [Job(m.name, str(s), None) for m in methods for s in (cfg.train_seeds if m.learned else ["-"])]
    jobs += [Job(m, f"n{n}", n) for n in cfg.data_efficiency for m in DATA_EFFICIENCY_METHODS]
    return _PreparedStudy(cfg, layout, folder, methods, base_env, roots, keys, generation, timings, jobs,
                          started)  # fmt: skip


def _run_prepared(runs: list[_PreparedStudy], meter: CostMeter) -> list[dict]:
    """Stages 2-3 of every study in one pool, then each study's cross-check and report (stage 4)."""
    jobs = [replace(j, study=i) for i, r in enumerate(runs) for j in r.jobs]
    processes = job_processes(runs[0].cfg, len(jobs))
    slurm = runs[0].cfg.executor == "slurm"  # the missing stages as cluster jobs (report.cluster)
    for r in runs:
        _stage(f"2-3/4 train and evaluate: {', '.join(m.name for m in r.methods)} (learned: seeds {r.cfg.train_seeds})")
    where = "as SLURM jobs" if slurm else f"in {processes} process{'es' if processes > 1 else ''}"
    print(
        f"evaluation: stock LeRobot eval_policy, in process; the same seeds for every method; {len(jobs)} runs "
        f"(method x training seed{', of every study' if len(runs) > 1 else ''}) {where}",
        flush=True,
    )
    if processes > 1 or slurm:  # a trained method's suites spread over the free processes (or cluster jobs)
        jobs = split_jobs(jobs, {j: job_suites(j, runs[j.study].cfg, runs[j.study].base_env) for j in jobs})
    if processes > 1 and not slurm:  # each cross-check's lerobot-eval run in the pool, not after it on one core
        jobs += [j for i, r in enumerate(runs) if (j := cross_check.cli_job(r.cfg, r.methods, i, jobs)) is not None]
    contexts = tuple(r.context for r in runs)
    if slurm:
        from lerobot_pnp.report.cluster import run_on_slurm

        finished, processes = run_on_slurm(jobs, contexts, runs[0].cfg, [r.layout.out for r in runs], _study_job)
        processes = max(1, processes)  # the cluster jobs submitted
    else:
        finished = dict(run_jobs(jobs, (contexts,), processes, fn=_study_job))
    meter.processes = processes
    meter.stage("jobs")
    for result in finished.values():
        for what, (done, total) in result.ran.items():
            meter.count(what, done, total)
        meter.job_rss_mb = max(meter.job_rss_mb, result.rss_mb)
    return [_finish(r, [j for j in jobs if j.study == i], finished, meter) for i, r in enumerate(runs)]


def _study_job(job: Job, contexts: tuple):
    """``run_job`` (or the cross-check's run, ``cross_check.cli_job``) in the context of the job's study (a
    module-level function: the pool pickles it)."""
    if job.part == CLI_CHECK:
        return cross_check.run_cli_job(job, *contexts[job.study])
    return run_job(job, *contexts[job.study])


def _finish(run: _PreparedStudy, jobs: list[Job], finished: dict, meter: CostMeter) -> dict:
    """The study's results from its jobs, the `lerobot-eval` cross-check and the report."""
    from lerobot_pnp.report.writer import StudyInputs, write_report

    cfg, layout, timings = run.cfg, run.layout, run.timings
    results: dict[str, dict[str, dict[str, list]]] = {}  # method -> tag -> suite -> records, in job order
    left: list[coverage.LeftOut] = []  # what report_only could not show (coverage)
    for job in jobs:
        result = finished[job]
        timings.update(result.timings)
        left += result.left
        for suite, recs in result.records.items():
            results.setdefault(job.method, {}).setdefault(job.tag, {})[suite] = recs
    results, left = coverage.withhold(results, left)

    cli_check = cross_check.cli_check(cfg, run.methods, results, (layout, run.roots, run.keys), timings)
    if cli_check is not None and "left_out" not in cli_check and not any(j.part == CLI_CHECK for j in jobs):
        meter.count("cli_checks", int("cli_check" in timings), 1)  # run here (the pool's job counted its own)
    meter.stage("cli_check")
    timings["run/wall_clock"] = time.perf_counter() - run.started  # this invocation, all processes together
    timings["run/processes"] = meter.processes

    _stage(f"4/4 report ({layout.out})")
    run.folder.claim(*layout.report_names())
    aliases = coverage.suite_aliases(suites_for(cfg, None), run.base_env)
    study = StudyInputs(cfg, run.methods, results, run.base_env, run.generation, timings, machine(), command(),
                        cli_check, left, {a: of for a, of in aliases.items() if a != of})  # fmt: skip
    summary = write_report(layout, study)
    print(f"\nreport: {layout.report}")
    meter.stage("report")
    return summary
