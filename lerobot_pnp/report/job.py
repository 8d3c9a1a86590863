"""What one job of the study does (``schedule.Job``): train a method x seed when one of its evaluations is
missing or stale, then run those evaluations, each keyed and recorded on disk (``stages``), so an interrupted
study resumes; a fixed-n record is reused cut to where an episode rule stops, when exact.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

from lerobot_pnp.cache import Stage
from lerobot_pnp.evaluation.records import records_from_json, records_to_json
from lerobot_pnp.integration.recorded_task import read_recorded
from lerobot_pnp.outputs import write_json_atomic
from lerobot_pnp.report import coverage
from lerobot_pnp.report.config import StudyConfig, SuiteSpec
from lerobot_pnp.report.cost import max_rss_mb
from lerobot_pnp.report.layout import StudyLayout
from lerobot_pnp.report.methods import TrainContext, get_methods, keyed_train, train_stage
from lerobot_pnp.report.schedule import ALL, TRAINING, Job
from lerobot_pnp.report.stages import episode_rule, eval_stage, truncated_record
from lerobot_pnp.sim.suites import get_suites

TRAIN_TIME = "study_train_time.json"  # in a training folder: how long its training took (reported when reused)


class JobResult(NamedTuple):
    """What a job hands back: the records per suite (aliases included), its stage timings, what ``report_only``
    left out, what it did itself (``ran``: trainings and evaluations, [done now, the job's]; ``cost.CostMeter``)
    and the peak resident set of the process it ran in, in MB."""

    records: dict
    timings: dict
    left: list
    ran: dict
    rss_mb: float


def train_context(
    job: Job, method, cfg: StudyConfig, layout: StudyLayout, roots: dict[str, Path], keys: dict[str, str]
):
    """What the job's method x seed trains with: its recording, training folder, seed, budget and the keys of
    the recordings (``methods.TrainContext``)."""
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
    pairs = suites_for(cfg, job.n_demos, method)
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
    pairs = suites_for(cfg, job.n_demos, method)
    aliases = coverage.suite_aliases(pairs, base_env)
    return [s.name for s, _ in pairs if aliases[s.name] == s.name]


def _train(method, ctx: TrainContext, job: Job, timings: dict, ran: dict):
    """The job's trained artefact (trained now, or found on disk); its training time into ``timings``, and into
    ``ran`` whether it was trained now."""
    t = time.perf_counter()
    artifact, fresh = keyed_train(method, ctx)
    if fresh:  # trained now, not found from an earlier run
        ran["trainings"][0] = 1
        write_json_atomic(ctx.train_dir / TRAIN_TIME, {"wall_s": time.perf_counter() - t})
        print(f"  trained {method.name} seed {job.tag}: {time.perf_counter() - t:.0f} s", flush=True)
    return artifact


def run_job(job: Job, cfg: StudyConfig, layout: StudyLayout, roots: dict[str, Path], base_env, keys: dict[str, str]):
    """Train ``job`` if one of its evaluations is missing or stale, run those evaluations (``job.part``: all of
    it, the training alone or one suite); return the records per suite, the stage timings and what
    ``report_only`` left out (``coverage.LeftOut``), as a ``JobResult``. Suites of the same effective conditions
    are evaluated once (``coverage.suite_aliases``). Everything it finishes is on disk, so an interrupted study
    resumes."""
    import torch

    torch.set_num_threads(1)
    (method,) = get_methods([job.method])
    ctx = train_context(job, method, cfg, layout, roots, keys)
    records, timings, left, artifact = {}, {}, [], None
    ran = {"trainings": [0, int(method.learned and job.part in (ALL, TRAINING))], "evaluations": [0, 0]}
    evaluations = _evaluations(job, method, ctx, cfg, layout, base_env)
    if job.part == TRAINING:
        if method.learned and not cfg.report_only and any(e.needed for e in evaluations):
            _train(method, ctx, job, timings, ran)
        evaluations = []
    elif job.part != ALL:
        evaluations = [e for e in evaluations if e.suite.name == job.part]
    for ev in evaluations:
        suite, names, stage = ev.suite, ev.names, ev.stages[0] if ev.finished is None else ev.finished
        ran["evaluations"][1] += 1
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
                artifact = _train(method, ctx, job, timings, ran)
            data = evaluate(method, artifact, ctx, suite, ev.n_episodes, base_env, cfg, ev.rule)
            stage.commit(**data)  # the record and the episodes in one atomic write
            ran["evaluations"][0] += 1
            ok = sum(e["success"] for e in data["episodes"])
            print(
                f"  {method.name:<13} {job.tag:>5} {suite.name:<16} {ok}/{len(data['episodes'])} ({data['wall_s']:.0f} s)",
                flush=True,
            )
        timings[f"eval/{method.name}/{job.tag}/{suite.name}"] = data["wall_s"]  # once, not once per alias
        records.update(dict.fromkeys(names, records_from_json(data)))
    if (wall_s := train_time(ctx.train_dir)) is not None:  # the time it took when it was trained (this run or earlier)
        timings[f"train/{method.name}/{job.tag}"] = wall_s
    return JobResult(records, timings, left, ran, max_rss_mb())


def train_time(train_dir: Path) -> float | None:
    """How long the training in ``train_dir`` took (``TRAIN_TIME``); None when it is not recorded as a number."""
    try:
        wall_s = json.loads((train_dir / TRAIN_TIME).read_text()).get("wall_s")
    except (OSError, ValueError, AttributeError):
        return None
    ok = isinstance(wall_s, int | float) and not isinstance(wall_s, bool) and math.isfinite(wall_s)
    return float(wall_s) if ok else None


def _first_cut(stages, rule, n_episodes: int, cfg: StudyConfig) -> dict | None:
    """The first of ``stages`` (a suite and its aliases) whose fixed-n record the rule can reuse, truncated."""
    return next((cut for st in stages if (cut := truncated_record(st, rule, n_episodes, cfg)) is not None), None)


def evaluate(method, artifact, ctx, suite, n_episodes: int, base_env, cfg: StudyConfig, rule=None) -> dict:
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


def suites_for(cfg: StudyConfig, n_demos: int | None, method=None):
    """(suite, episodes) pairs evaluated for a job; data-efficiency runs are evaluated on nominal only, a
    method with a ``suites`` list only on those."""
    specs = [SuiteSpec("nominal", 200)] if n_demos is not None else cfg.suites
    split = method is not None and method.learned and n_demos is None  # a cell pooling the training seeds
    pairs = [(s, cfg.seed_episodes(spec.n_episodes) if split else spec.n_episodes)
             for spec in specs for s in get_suites([spec.name])]  # fmt: skip
    if method is not None and method.suites is not None:
        pairs = [(s, n) for s, n in pairs if s.name in method.suites]
    return pairs
