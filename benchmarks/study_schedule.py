"""The wall clock a study would take from scratch, replayed from the job times a finished study recorded.

The study's pool (``report.schedule``) runs each study's datasets first, then every training and every suite's
evaluation as a job on one core each, a job starting once the one it waits for (``Job.after``: its training,
or the training it continues) has finished, in the pool's order (``schedule.ready``: an evaluation as soon as
its training is done, the others in ``longest_first`` order); the ``lerobot-eval`` cross-check is a job of the
pool too, after the nominal evaluation it is compared with (``cross_check.cli_job``). This script replays that schedule
on the recorded times: each training's ``study_train_time.json``, each evaluation record's ``wall_s`` and the
dataset stages' wall times given on the command line (a reused dataset records none). ``--eval-scale`` and
``--dataset-scale`` multiply the evaluation and dataset times, to project a measured speed-up of the env
(``bench_eval_env.py``) onto the whole study; the projection is only as good as that ratio.

    python benchmarks/study_schedule.py --study outputs/report_full --dataset-s 624 \\
        --study outputs/heldout --dataset-s 403 [--processes 2] [--eval-scale 0.75 --dataset-scale 0.75]

``--study`` also takes a study's ``summary.json`` (``timings_s``: every training and evaluation it recorded,
the data-efficiency runs and the ``lerobot-eval`` cross-check included), so a committed summary
(``docs/results/study/report_full/summary.json``) replays without its folder. ``--cli-after-pool`` replays the
cross-check after the pool, alone, as the study ran it before it was a job of the pool.

What a cut would save, before running it: ``--without STUDY:METHOD`` replays without every job of that method in
the ``--study`` given at that position (0 first; the cross-check stays when its method stays), and
``--train-scale`` multiplies the training times (fewer epochs: a training's time is about proportional to them).

    python benchmarks/study_schedule.py --study docs/results/study/report_full/summary.json --dataset-s 204 \
        --study docs/results/study/heldout/summary.json --dataset-s 145 --without 1:memoryless_mlp
"""

from __future__ import annotations

import argparse
import heapq
import json
from pathlib import Path
from types import SimpleNamespace

from lerobot_pnp.report.cross_check import cli_job
from lerobot_pnp.report.methods import get_methods
from lerobot_pnp.report.schedule import ALL, TRAINING, Job, longest_first, ready

TRAIN_TIME = "study_train_time.json"


def summary_jobs(summary: Path, study: int) -> tuple[list[Job], dict[tuple, float], float]:
    """The jobs of a study's ``summary.json`` (``timings_s``: ``train/<method>/<tag>`` and
    ``eval/<method>/<tag>/<suite>``, data-efficiency tags ``n<demos>`` included), their recorded times (s), and
    the ``lerobot-eval`` cross-check's time."""
    data = json.loads(summary.read_text())
    timings = data["timings_s"]
    jobs, times = [], {}
    for name, seconds in timings.items():
        kind, *rest = name.split("/")
        if kind == "train":
            (method, tag), part = rest, TRAINING
        elif kind == "eval":
            method, tag, part = rest
        else:
            continue
        job = Job(method, tag, int(tag[1:]) if tag.startswith("n") else None, part, study)
        jobs.append(job)
        times[job.key] = float(seconds)
    return jobs, times, float(timings.get("cli_check", 0.0)), data.get("config")


def with_cli_jobs(jobs: list[Job], times: dict, checks: list[tuple[int, float, dict | None]]) -> float:
    """Each study's cross-check (``checks``: study, recorded seconds, its config) added to ``jobs`` as the pool's
    job (``cross_check.cli_job``) where the pool runs it; returns the seconds of those left after the pool."""
    serial = 0.0
    for study, seconds, config in checks:
        job = None
        if config is not None:
            cfg = SimpleNamespace(**{**config, "report_only": False})
            job = cli_job(cfg, get_methods(config["methods"]), study, jobs)
        if job is None:
            serial += seconds
        else:
            jobs.append(job)
            times[job.key] = seconds
    return serial


def study_jobs(out: Path, study: int) -> tuple[list[Job], dict[tuple, float]]:
    """The jobs of a finished study folder (each method x seed: its training, one job per evaluated suite) and
    their recorded times (s)."""
    cfg = json.loads((out / "study_config.json").read_text())
    jobs, times = [], {}
    for method in get_methods(cfg.get("methods")):
        tags = [str(s) for s in cfg["train_seeds"]] if method.learned else ["-"]
        for tag in tags:
            if method.learned:
                train = Job(method.name, tag, None, TRAINING, study)
                record = out / "train" / method.name / f"seed{tag}" / TRAIN_TIME
                times[train.key] = json.loads(record.read_text())["wall_s"] if record.is_file() else 0.0
                jobs.append(train)
            for record in sorted((out / "evals" / method.name / f"seed{tag}").glob("*.json")):
                job = Job(method.name, tag, None, record.stem, study)
                times[job.key] = json.loads(record.read_text()).get("wall_s", 0.0)
                jobs.append(job)
    return jobs, times


def replay(jobs: list[Job], times: dict[tuple, float], processes: int, order=ready) -> float:
    """Wall time of ``jobs`` on ``processes`` cores under the study's order (``order``: the pool's
    ``schedule.ready``) and dependencies."""
    names = {j.key for j in jobs}
    pending, running, done, clock = longest_first(jobs), [], set(), 0.0
    while pending or running:
        for job in order(pending, names, done)[: processes - len(running)]:
            pending.remove(job)
            heapq.heappush(running, (clock + times[job.key], job.key))
        if not running:
            raise SystemExit(f"jobs wait on something that never runs: {[j.key for j in pending][:5]}")
        clock, key = heapq.heappop(running)
        done.add(key)
    return clock


def in_order(pending: list[Job], names: set, done: set) -> list[Job]:
    """The jobs that can start now in ``longest_first`` order alone (every training before the evaluations that
    wait for one): ``--order longest_first``, the pool's order before ``schedule.ready``."""
    return [j for j in pending if j.after() not in names or j.after() in done]


ORDERS = {"ready": ready, "longest_first": in_order}


def replay_studies(studies: list[Path], processes: int = 2, order=ready, cli_in_pool: bool = True,
                   eval_scale: float = 1.0, without: tuple[tuple[int, str], ...] = (),
                   train_scale: float = 1.0) -> dict:  # fmt: skip
    """The replayed pool of ``studies`` (folders or ``summary.json`` files, run alongside in one pool): its wall
    seconds (``pool_s``), the cross-checks left after it (``serial_s``), and the job seconds of the trainings and
    of the evaluations (the cross-checks included) it packs. ``without``: (study position, method) pairs whose
    jobs are left out; ``train_scale`` multiplies every training's time."""
    jobs, times, checks = [], {}, []
    for i, out in enumerate(studies):
        if out.is_file():
            j, t, check, config = summary_jobs(out, i)
            checks.append((i, check, config if cli_in_pool and processes > 1 else None))  # one process: after
        else:
            j, t = study_jobs(out, i)
        kept = [job for job in j if (i, job.method) not in without]
        jobs += kept
        times.update({job.key: t[job.key] for job in kept})
    serial = with_cli_jobs(jobs, times, checks)
    scale = {TRAINING: train_scale, ALL: 1.0}
    times = {k: v * scale.get(k[2], eval_scale) for k, v in times.items()}
    train = sum(v for k, v in times.items() if k[2] == TRAINING)
    return {"jobs": len(jobs), "train_s": train, "eval_s": sum(times.values()) - train,
            "pool_s": replay(jobs, times, processes, order), "serial_s": serial}  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--study", type=Path, action="append", required=True, help="a finished study folder, or its summary.json"
    )
    p.add_argument("--dataset-s", type=float, action="append", default=None, help="its dataset stages' wall s")
    p.add_argument("--processes", type=int, default=2)
    p.add_argument("--eval-scale", type=float, default=1.0)
    p.add_argument("--dataset-scale", type=float, default=1.0)
    p.add_argument("--order", choices=sorted(ORDERS), default="ready", help="the pool's order of ready jobs")
    p.add_argument("--cli-after-pool", action="store_true", help="the cross-checks after the pool, one at a time")
    p.add_argument("--without", action="append", default=[], metavar="STUDY:METHOD",
                   help="leave out a method's jobs in the --study at that position (0 first)")  # fmt: skip
    p.add_argument("--train-scale", type=float, default=1.0, help="multiply every training's time")
    args = p.parse_args(argv)
    try:
        without = tuple((int(w.split(":")[0]), w.split(":", 1)[1]) for w in args.without)
    except (ValueError, IndexError):
        raise SystemExit(f"--without takes STUDY:METHOD (a --study's position, 0 first): got {args.without}") from None
    datasets = args.dataset_s or [0.0] * len(args.study)
    if len(datasets) != len(args.study):
        raise SystemExit("give one --dataset-s per --study")
    r = replay_studies(
        args.study,
        args.processes,
        ORDERS[args.order],
        not args.cli_after_pool,
        args.eval_scale,
        without,
        args.train_scale,
    )
    data = sum(datasets) * args.dataset_scale
    wall = data + r["pool_s"] + r["serial_s"]
    print(
        f"{r['jobs']} jobs: training {r['train_s']:.0f} s + evaluation {r['eval_s']:.0f} s of job time; "
        f"datasets {data:.0f} s wall, then the pool of {args.processes}: {r['pool_s']:.0f} s, then the "
        f"cross-checks left after it {r['serial_s']:.0f} s "
        f"(job time / pool wall = {(r['train_s'] + r['eval_s']) / r['pool_s']:.2f}); total {wall:.0f} s = "
        f"{wall / 3600:.2f} h"
    )


if __name__ == "__main__":
    main()
