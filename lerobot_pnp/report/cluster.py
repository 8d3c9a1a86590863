"""The study's jobs as SLURM jobs (``--executor slurm``), submitted with submitit.

The job graph is the local pool's (``report.schedule``): each dataset, then every method x seed's training
and its suites' evaluations, a job waiting for the one it continues (``Job.after``), then the report. Only the
jobs whose stages have no valid record are submitted (the stage keys of ``report.stages`` decide, as for a
local run), grouped into cluster jobs (``StudySlurmOptions.suites_per_job``): the jobs that wait on nothing in
one job array, each group waiting on the same job in one array with ``--dependency afterok`` on it. A job
writes its stages as the local pool's processes do (each record committed whole, after its outputs); the
submitting process holds the study folder's lock while it waits, then reads every result from the records on
disk, so the folder stays the one source of truth. The ids of the jobs it submitted are kept in the folder
(``slurm/jobs.json``): a later run refuses the folder while any of them is still queued or running.

submitit, not datatrove's executor (which the generation uses): the study's jobs form a graph of different
functions, each with its own dependency, where datatrove runs the ranks of one pipeline with one dependency per
array and keeps its own completion records, a second bookkeeping beside the stage keys.
"""

from __future__ import annotations

import contextlib
import io
import json
import signal
import subprocess
import time
from pathlib import Path

from lerobot_pnp.cache import STAGE_FILE, Stage
from lerobot_pnp.dataset.executors import active_slurm_jobs, slurm_available
from lerobot_pnp.errors import ClusterJobError, one_line
from lerobot_pnp.outputs import write_json_atomic
from lerobot_pnp.report.layout import CLUSTER_DIR
from lerobot_pnp.report.schedule import TRAINING, Job

JOBS_FILE = "jobs.json"
POLL_S = (0.5, 10.0)  # seconds between two looks at the queue: at first, and at most (a long wait looks less often)


def check_available() -> None:
    """Refuse ``--executor slurm`` (one line) where SLURM's client binaries are missing: before the study writes
    anything."""
    if not slurm_available():
        raise ClusterJobError("--executor slurm: sbatch/squeue not found on PATH (is this a SLURM login node?)")


def refuse_live_jobs(out: Path) -> None:
    """Refuse ``out`` while a cluster job an earlier run submitted for it is queued or running (its submitting
    process was killed): a second run would write the same stages beside it."""
    try:
        ids = json.loads((out / CLUSTER_DIR / JOBS_FILE).read_text())["job_ids"]
    except (OSError, ValueError, KeyError, TypeError):
        return
    if live := active_slurm_jobs([str(i) for i in ids]):
        raise ClusterJobError(
            f"cluster jobs of an earlier run on {out} are still queued or running (SLURM ids {', '.join(live[:5])}); "
            "wait for them to end or scancel them, then run the command again"
        )


# ------------------------------------------------------------------------------------------------ in the job
def _run_task(jobs: list[Job], contexts: tuple, processes: int, fn) -> list[tuple]:
    """One cluster job: its study jobs, in order or in a pool of its CPUs (``schedule.run_jobs``), each leaving
    its stages on disk. A cancelled job stops at once (SLURM's SIGTERM, which submitit would ignore until
    SLURM's kill): what it finished is recorded, the rest stays missing and is resubmitted by the next run."""
    from lerobot_pnp.report.schedule import run_jobs

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    for _ in run_jobs(jobs, (contexts,), max(1, min(processes, len(jobs))), fn=fn):
        pass
    return [j.key for j in jobs]


def _dataset_task(out: Path, name: str, cfg, changes: dict | None):
    from lerobot_pnp.report.stages import dataset_stage

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    return dataset_stage(out, name, cfg, changes)


# ------------------------------------------------------------------------------------------ the submitter
def missing(job: Job, context: tuple) -> bool:
    """Whether ``job`` (a training or one suite's evaluation) has a stage without a valid record: what a cluster
    job must do (the same test as ``job.run_job``'s)."""
    from lerobot_pnp.report.job import _evaluations, train_context
    from lerobot_pnp.report.methods import get_methods, train_stage

    cfg, layout, roots, base_env, keys = context
    (method,) = get_methods([job.method])
    ctx = train_context(job, method, cfg, layout, roots, keys)
    evaluations = _evaluations(job, method, ctx, cfg, layout, base_env)
    if job.part == TRAINING:
        return method.learned and any(e.needed for e in evaluations) and train_stage(method, ctx).changes() != []
    return any(e.needed for e in evaluations if e.suite.name == job.part)


def cluster_tasks(jobs: list[Job], suites_per_job: int) -> list[list[Job]]:
    """``jobs`` (trainings and one job per suite) grouped into cluster jobs: per method x seed, its training and
    every suite (``suites_per_job`` 0), or the training alone and its suites ``suites_per_job`` at a time."""
    runs: dict[tuple, list[Job]] = {}
    for job in jobs:
        runs.setdefault((job.method, job.tag, job.study), []).append(job)
    tasks: list[list[Job]] = []
    for run in runs.values():
        training = [j for j in run if j.part == TRAINING]
        suites = [j for j in run if j.part != TRAINING]
        if suites_per_job == 0:
            tasks.append(training + suites)
            continue
        tasks += [training] if training else []
        tasks += [suites[i : i + suites_per_job] for i in range(0, len(suites), suites_per_job)]
    return tasks


def _waits_on(tasks: list[list[Job]]) -> list[int | None]:
    """The task each task waits for (the one holding a job its jobs wait on), or None."""
    owner = {j.key: i for i, task in enumerate(tasks) for j in task}
    out = []
    for i, task in enumerate(tasks):
        before = {owner[a] for j in task if (a := j.after()) in owner and owner[a] != i}
        assert len(before) <= 1, f"a cluster job waits on several: {task}"
        out.append(before.pop() if before else None)
    return out


class Submitter:
    """Submits cluster jobs (submitit's ``SlurmExecutor``) for the study folders ``outs`` and waits for them;
    the job ids go into every folder's ``JOBS_FILE`` as they are submitted."""

    def __init__(self, outs: list[Path], options, workers: int):
        import submitit

        check_available()
        self.outs, self.options, self.ids = outs, options, []
        self.folder = outs[0] / CLUSTER_DIR
        self.executor = submitit.SlurmExecutor(folder=self.folder / "%j", max_num_timeout=0)
        self.base = {
            "partition": options.partition,
            "time": options.time,
            "mem_per_cpu": f"{options.mem_per_cpu_gb}G",
            "job_name": options.job_name,
            "array_parallelism": workers if workers > 0 else 1000,
            "qos": options.qos,
            # a job whose dependency failed is cancelled, not left pending for ever
            "additional_parameters": {"kill-on-invalid-dep": "yes"},
        }

    def submit(self, fn, calls: list[tuple], cpus: int, after: str | None = None) -> list:
        """``fn(*args)`` for each of ``calls``, as one job array (one job for one call)."""
        self.executor.update_parameters(
            **self.base, cpus_per_task=cpus, dependency=f"afterok:{after}" if after else None
        )
        try:  # sbatch's refusal is this command's one line, not also printed by submitit
            with contextlib.redirect_stderr(io.StringIO()), self.executor.batch():  # submitted on leaving batch()
                jobs = [self.executor.submit(fn, *args) for args in calls]
        except Exception as err:  # sbatch refused: an unknown partition, a time over the partition's limit ...
            raise ClusterJobError(f"sbatch refused the study's jobs: {one_line(err)}") from None
        self.ids += [j.job_id for j in jobs]
        for out in self.outs:
            write_json_atomic(out / CLUSTER_DIR / JOBS_FILE, {"job_ids": self.ids})
        return jobs

    def wait(self, jobs: list, what: list[str]) -> list:
        """Each job's result, once every job has left the queue; a job that failed or was cancelled is one line
        naming it, its error and its log, after the others ended (the folder lock held until then). Interrupted:
        every job still queued or running is cancelled."""
        ended: dict[int, tuple[bool, object]] = {}
        gone: set[int] = set()  # out of the queue without a result at the last look (a result may lag on NFS)
        started = time.monotonic()
        try:
            while len(ended) < len(jobs):
                live = _queued([j.job_id for i, j in enumerate(jobs) if i not in ended])
                for i, job in enumerate(jobs):  # ended: out of the queue, so nothing of it writes on
                    if i in ended or live is None or job.job_id in live:
                        continue
                    if job.paths.result_pickle.exists():
                        error = job.exception()
                        ended[i] = (error is None, error if error is not None else job.result())
                    elif i in gone:  # no result, twice: cancelled, killed, out of time
                        ended[i] = (False, None)
                    else:
                        gone.add(i)
                if len(ended) < len(jobs):
                    time.sleep(min(POLL_S[1], POLL_S[0] + (time.monotonic() - started) / 60))
        except BaseException:
            for i, job in enumerate(jobs):
                if i not in ended:
                    job.cancel(check=False)
            raise
        failed = [i for i, (ok, _) in ended.items() if not ok]
        if failed:
            raise ClusterJobError(self._failure(jobs, what, ended, sorted(failed)))
        return [ended[i][1] for i in range(len(jobs))]

    def _failure(self, jobs, what, ended, failed) -> str:
        first = failed[0]
        error = ended[first][1]
        lines = [line for line in str(error or "").splitlines() if line.strip()]
        why = lines[-1].strip()[:300] if lines else "no result: cancelled, killed or out of time"
        return (
            f"{len(failed)} of {len(jobs)} cluster jobs failed or were cancelled (SLURM {jobs[first].job_id}: "
            f"{what[first]}: {why}; log {jobs[first].paths.stderr}); what the jobs finished is recorded: run the "
            "same command again to submit only what is missing"
        )


def _queued(ids: list[str]) -> set[str] | None:
    """The ids among ``ids`` SLURM still has queued or running (None when squeue does not answer)."""
    if not ids:
        return set()
    res = subprocess.run(["squeue", "-h", "-r", "-o", "%i", "-j", ",".join(ids)], capture_output=True, text=True,
                         timeout=60)  # fmt: skip
    if res.returncode != 0 and "Invalid job id" not in res.stderr:
        return None
    return set(res.stdout.split())


def run_on_slurm(jobs: list[Job], contexts: tuple, cfg, outs: list[Path], fn) -> tuple[dict, int]:
    """Stages 2-3 as cluster jobs: the jobs (trainings and one job per suite) whose stages are missing are
    submitted and waited for; then every job's results are read from the records on disk, in this process.
    Returns them as ``schedule.run_jobs`` would, and the number of cluster jobs submitted."""
    from lerobot_pnp.report.schedule import run_jobs

    todo = [] if cfg.report_only else [j for j in jobs if missing(j, contexts[j.study])]
    tasks = cluster_tasks(todo, cfg.slurm.suites_per_job)
    if tasks:
        _submit_tasks(tasks, contexts, cfg, outs, fn)
        if left := [j for j in todo if missing(j, contexts[j.study])]:  # a job ended well without its record
            raise ClusterJobError(
                f"the cluster jobs ended, but {len(left)} stages have no record: {_describe(left[:1])}"
            )
    return dict(run_jobs(jobs, (contexts,), 1, fn=fn)), len(tasks)


def _submit_tasks(tasks: list[list[Job]], contexts: tuple, cfg, outs: list[Path], fn) -> None:
    """Submit ``tasks`` in waves (an array per group waiting on the same job), then wait for all of them."""
    submitter = Submitter(outs, cfg.slurm, cfg.workers)
    waits, submitted = _waits_on(tasks), {}
    cpus = cfg.slurm.cpus_per_task
    try:
        while len(submitted) < len(tasks):
            groups: dict[int | None, list[int]] = {}
            for i, before in enumerate(waits):
                if i not in submitted and (before is None or before in submitted):
                    groups.setdefault(before, []).append(i)
            for before, members in groups.items():
                after = None if before is None else submitted[before].job_id
                calls = [(tasks[i], contexts, cpus, fn) for i in members]
                submitted.update(zip(members, submitter.submit(_run_task, calls, cpus, after), strict=True))
    except BaseException:  # a refused or interrupted submission leaves no job of this run behind
        for job in submitted.values():
            job.cancel(check=False)
        raise
    order = sorted(submitted)
    print(f"  submitted {len(tasks)} cluster jobs (SLURM {', '.join(submitted[i].job_id for i in order[:8])}"
          f"{' ...' if len(order) > 8 else ''}); logs: {submitter.folder}", flush=True)  # fmt: skip
    submitter.wait([submitted[i] for i in order], [_describe(tasks[i]) for i in order])


def _describe(task: list[Job]) -> str:
    j = task[0]
    parts = ", ".join(x.part for x in task)
    return f"{j.method} {j.tag} ({parts})"


def dataset_on_slurm(out: Path, name: str, cfg, changes: dict | None = None) -> tuple[dict, str]:
    """``stages.dataset_stage`` as a cluster job (``--slurm.dataset_cpus`` shard workers) when the dataset has
    no valid record; in this process when it has one (reused) or nothing is generated (``report_only``)."""
    from dataclasses import replace

    from lerobot_pnp.report.stages import dataset_parts, dataset_stage

    if cfg.report_only or Stage(out / name / STAGE_FILE, dataset_parts(cfg, changes)).changes() == []:
        return dataset_stage(out, name, cfg, changes)
    cpus = cfg.slurm.dataset_cpus or cfg.slurm.cpus_per_task
    submitter = Submitter([out], cfg.slurm, cfg.workers)
    (job,) = submitter.submit(_dataset_task, [(out, name, replace(cfg, workers=cpus), changes)], cpus)
    print(f"  dataset {name}: cluster job SLURM {job.job_id} ({cpus} CPUs); logs: {submitter.folder}", flush=True)
    (result,) = submitter.wait([job], [f"dataset {name}"])
    return result
