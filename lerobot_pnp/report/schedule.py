"""The study's jobs and their schedule: a method x training seed as its training and one job per suite, run
in a process pool, a job starting once the one it waits for has finished: an evaluation as soon as its training
is done, the other jobs the likely longest first.

What one job does is ``report.job``; the stages around the pool, ``report.run``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace

from lerobot_pnp.report.config import StudyConfig
from lerobot_pnp.report.methods import get_methods

# ``Job.part``: a method x seed's training and every suite in one job (one process), or the training alone, or
# the study's `lerobot-eval` cross-check (``cross_check.cli_job``); any other part is a suite's evaluation
ALL, TRAINING, CLI_CHECK = "*", "training", "cli_check"

# what every training or evaluation job imports, loaded once by the pool's fork server (no MuJoCo: its GL backend
# is chosen where an env is built)
JOB_IMPORTS = ("lerobot_pnp.train_fast", "lerobot_pnp.evaluation.closed_loop", "lerobot.policies.factory")


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
        training of the same seed that its method continues (DAgger); the cross-check waits for the nominal
        evaluation it is compared with."""
        method = get_methods([self.method])[0]
        if self.part == CLI_CHECK:
            return self.method, self.tag, "nominal", self.study
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


def job_processes(cfg: StudyConfig, n_jobs: int) -> int:
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, min(n_jobs, cfg.workers or cores))


def longest_first(jobs: list[Job]) -> list[Job]:
    """The order a pool considers jobs in (``ready`` takes those that waited for a finished job first): the
    likely longest first, so that the last job to finish is a short one and no core idles while one long job
    runs on alone (longest-processing-time scheduling). A job's class:
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


def ready(pending: list[Job], names: set, done: set) -> list[Job]:
    """The jobs of ``pending`` (in ``longest_first`` order) that can start now, in the order the pool takes them:
    first those that waited for a job now done (a suite's evaluation once its training is done, the cross-check),
    so that a checkpoint is evaluated as soon as it exists and the first results come early; then the others in
    their order. The wall clock is the same either way while the pool is full (``benchmarks/study_schedule.py``
    replays both): what runs first changes, not what each job computes (each is single-threaded and keyed)."""
    free = [j for j in pending if j.after() not in names or j.after() in done]
    waited = [j for j in free if j.after() in done and j.part not in (ALL, TRAINING)]
    return waited + [j for j in free if j not in waited]


def run_jobs(jobs: list[Job], context: tuple, processes: int, fn):
    """Yield ``(job, fn(job, *context))`` for every job (``fn``: a module-level function, e.g. ``job.run_job``).
    One process: in order, in this process. Several: a spawned process pool (each job is single-threaded: torch
    and MuJoCo on one core), a job starting once the job it continues has finished; results come in order of
    completion."""
    if processes == 1:
        for job in jobs:
            yield job, fn(job, *context)
        return
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    names = {j.key for j in jobs}
    done: set[tuple[str, str, str, int]] = set()
    pending, running = longest_first(jobs), {}
    from lerobot_pnp.dataset.executors import die_with_forking_parent

    # Workers fork from multiprocessing's fork server, which imports what the jobs import (torch, LeRobot) once:
    # a spawned worker would import it again each. The server is a fresh interpreter, not a fork of this
    # process and its threads. A worker dies with this process (kill -9 included), as the generation's do: none
    # writes on alone.
    server = mp.get_context("forkserver")
    server.set_forkserver_preload([fn.__module__, *JOB_IMPORTS])
    pool = ProcessPoolExecutor(
        processes, mp_context=server, initializer=die_with_forking_parent, initargs=(os.getpid(),)
    )
    with pool:
        while pending or running:
            for job in ready(pending, names, done)[: processes - len(running)]:
                pending.remove(job)
                running[pool.submit(fn, job, *context)] = job
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in finished:
                job = running.pop(future)
                done.add(job.key)
                yield job, future.result()
