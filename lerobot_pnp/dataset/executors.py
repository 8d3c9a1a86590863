"""Running the shard step with datatrove: on this machine (``LocalPipelineExecutor``) or on SLURM.

Datatrove owns the process pool, the per-task logs and the completion records that make a rerun skip
finished ranks. This module adds what a terminal user needs on top: datatrove's and LeRobot's log lines go
to ``<logging_dir>/console.log`` instead of the terminal, and one tqdm bar counts episodes (read from the
small per-rank progress files the shards write, so it works the same for any number of workers).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import select
import shutil
import signal
import subprocess
import sys
import threading
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from lerobot_pnp.errors import ConfigError, DatasetError
from lerobot_pnp.support.slurm_fields import check_slurm_fields


def default_workers() -> int:
    """One worker per CPU core this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


@contextlib.contextmanager
def console_to_file(log_path: Path):
    """Send this process's stderr (fd 2, inherited by spawned workers) to ``log_path``; yield a stream to the
    real terminal for the progress bar."""
    log_path.parent.mkdir(parents=True, exist_ok=True)
    sys.stderr.flush()
    saved = os.dup(2)
    with open(log_path, "ab") as log:
        os.dup2(log.fileno(), 2)
    terminal = os.fdopen(os.dup(saved), "w", buffering=1)
    try:
        yield terminal
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)
        terminal.close()


class ProgressBar:
    """One tqdm bar over all ranks: polls ``progress/<rank>`` files ("<episodes> <failures>")."""

    def __init__(self, progress_dir: Path, total: int, stream, enabled: bool, initial: int = 0):
        from tqdm import tqdm

        self.dir, self.initial = progress_dir, initial
        from lerobot_pnp.support.progress import redraw_interval_s

        # redrawn twice a second on a terminal; into a log (no terminal) only every 15 s, so a log
        # gets a line of progress now and then instead of a flood of carriage-return updates
        self.interval = redraw_interval_s(stream)
        self.bar = tqdm(
            total=total, initial=initial, desc="episodes", unit="ep", file=stream, disable=not enabled, smoothing=0.05
        )
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, daemon=True)

    def _read(self) -> tuple[int, int]:
        eps = fails = 0
        for path in self.dir.glob("*"):
            try:
                e, f = (int(v) for v in path.read_text().split())
            except (OSError, ValueError):  # being written, or just removed
                continue
            eps, fails = eps + e, fails + f
        return eps, fails

    def _poll(self) -> None:
        while not self._stop.wait(self.interval):
            self.update()

    def update(self) -> None:
        eps, fails = self._read()
        self.bar.n = min(self.bar.total, self.initial + eps)
        if fails:
            self.bar.set_postfix(expert_failures=fails, refresh=False)
        self.bar.refresh()

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        if exc[0] is None:
            self.update()
        self.bar.close()


def die_with_parent(parent_pid: int | None) -> None:
    """A helper process must not outlive the `generate` process that started it (kill -9 included), or it
    would finish its shard while a resumed run rebuilds the same shard.

    The kernel sends SIGKILL to this process when its parent dies (PR_SET_PDEATHSIG); the parent check right
    after closes the window where the parent died before the request was made.
    """
    if parent_pid is None or os.getpid() == parent_pid:  # in-process run, or a SLURM task
        return
    with contextlib.suppress(OSError):  # not Linux: the shards also check their parent per episode
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG = 1
    if os.getppid() != parent_pid:
        os._exit(1)


def die_with_forking_parent(owner_pid: int | None) -> None:
    """``die_with_parent`` for a worker forked by multiprocessing's fork server on behalf of ``owner_pid``.

    The worker's parent is the server, which outlives the owner while any worker runs, so the parent-death signal
    cannot tell: a daemon thread waits on the owner's process descriptor (Linux; elsewhere it polls the pid) and
    ends the worker the moment the owner is gone, kill -9 included.
    """

    if owner_pid is None or os.getpid() == owner_pid:  # in-process run, or a SLURM task
        return

    def watch(pidfd: int | None) -> None:
        if pidfd is not None:
            select.select([pidfd], [], [])
        while pidfd is None and owner_alive(owner_pid):
            time.sleep(1.0)
        os._exit(1)

    try:
        pidfd = os.pidfd_open(owner_pid) if hasattr(os, "pidfd_open") else None
    except ProcessLookupError:
        os._exit(1)
    except OSError:
        pidfd = None
    threading.Thread(target=watch, args=(pidfd,), name="die-with-owner", daemon=True).start()


def owner_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class _ForkGuard:
    """Registered with multiprocess's after-fork hooks: datatrove's Manager server is a *forked* child of
    this process, which would otherwise survive a kill -9 of it (and keep its stdout/stderr open)."""

    pid: int | None = None

    @staticmethod
    def after_fork(guard: _ForkGuard) -> None:
        die_with_parent(guard.pid)


_FORK_GUARD = _ForkGuard()


def run_local(step, tasks: int, workers: int, logging_dir: Path) -> None:
    """Run every incomplete rank of ``step`` on this machine (``workers`` at a time; 1 = in this process)."""
    import multiprocess.util

    if _FORK_GUARD.pid is None:
        multiprocess.util.register_after_fork(_FORK_GUARD, _ForkGuard.after_fork)
    _FORK_GUARD.pid = os.getpid()
    with warnings.catch_warnings():
        # datatrove forks its Manager server while our progress thread runs; the server only serves a queue
        warnings.filterwarnings("ignore", r"This process .* is multi-threaded", DeprecationWarning)
        _run_executor(step, tasks, workers, logging_dir)


# what a shard imports, loaded once by the workers' fork server (no MuJoCo: its GL backend is chosen where an env
# is built)
SHARD_IMPORTS = ("lerobot_pnp.dataset.shards", "lerobot.datasets.lerobot_dataset", "lerobot.envs.configs")


def _run_executor(step, tasks: int, workers: int, logging_dir: Path) -> None:
    import multiprocess
    from datatrove.executor import LocalPipelineExecutor

    # Workers fork from a fork server (a fresh interpreter: no inherited threads or locks) that imports what a shard
    # imports once; a spawned worker would import torch and LeRobot again each.
    multiprocess.get_context("forkserver").set_forkserver_preload(list(SHARD_IMPORTS))
    executor = LocalPipelineExecutor(
        pipeline=[step],
        tasks=tasks,
        workers=max(1, min(workers, tasks)),
        logging_dir=str(logging_dir),
        start_method="forkserver",
    )
    executor.run()


def slurm_available() -> bool:
    return shutil.which("sbatch") is not None and shutil.which("squeue") is not None


def submit_slurm(shard_step, merge_step, tasks: int, options, logging_dir: Path, workers: int) -> list[str]:
    """Submit the shard array and the dependent merge job; return their SLURM job ids."""
    from datatrove.executor import SlurmPipelineExecutor

    if not slurm_available():
        raise DatasetError("--executor slurm: sbatch/squeue not found on PATH (is this a SLURM login node?)")
    common = {
        "time": options.time,
        "partition": options.partition,
        "cpus_per_task": options.cpus_per_task,
        "mem_per_cpu_gb": options.mem_per_cpu_gb,
        "qos": options.qos,
        # the job runs this interpreter's console scripts (launch_pickled_pipeline) with this environment
        "env_command": f"export PATH={Path(sys.executable).parent}:$PATH",
        "mail_type": "NONE",
        "requeue": True,
    }
    gen = SlurmPipelineExecutor(
        pipeline=[shard_step],
        tasks=tasks,
        workers=workers or -1,
        job_name=options.job_name,
        logging_dir=str(logging_dir / "shards"),
        **common,
    )
    merge = SlurmPipelineExecutor(
        pipeline=[merge_step],
        tasks=1,
        depends=gen,
        job_name=f"{options.job_name}_merge",
        logging_dir=str(logging_dir / "merge"),
        **common,
    )
    try:
        merge.run()
    except subprocess.CalledProcessError as err:
        raise DatasetError(f"sbatch failed ({err}); see {logging_dir}/console.log") from None
    return [str(j) for j in (gen.job_id, merge.job_id) if j not in (None, -1)]


def active_slurm_jobs(job_ids: list[str]) -> list[str]:
    """The ids among ``job_ids`` SLURM still has queued or running (empty when squeue is unavailable)."""
    if not job_ids or shutil.which("squeue") is None:
        return []
    res = subprocess.run(["squeue", "-h", "-j", ",".join(job_ids)], capture_output=True, text=True, timeout=30)
    return list(job_ids) if res.stdout.strip() else []  # finished jobs are unknown to squeue (empty/rc 1)


@dataclass
class SlurmOptions:
    """``--slurm.*``: resources of each SLURM array task (one shard) and of the merge job."""

    partition: str = "cpu"  # SLURM partition (sbatch --partition) of the shard tasks and the merge job
    cpus_per_task: int = 1  # CPUs per array task (sbatch --cpus-per-task)
    mem_per_cpu_gb: int = 2  # GB per CPU (an integer: sbatch rejects "1.5G")
    time: str = "04:00:00"  # per task, HH:MM:SS
    qos: str | None = None  # SLURM quality of service (sbatch --qos); none = the cluster default
    job_name: str = "pnp_generate"  # SLURM job name of the array; the merge job adds "_merge"

    def __post_init__(self):
        if self.cpus_per_task < 1 or self.mem_per_cpu_gb <= 0:
            raise ConfigError("slurm.cpus_per_task must be >= 1 and slurm.mem_per_cpu_gb > 0")
        check_slurm_fields(self)
