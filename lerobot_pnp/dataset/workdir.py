"""The output root of a generation: its layout, its lock, and what may be deleted in it.

While a run is in progress the root holds a work folder (and whatever unrelated files the user keeps there)::

    ROOT/.pnp_work/run.json                 the generation settings and the resolved env config of the run
    ROOT/.pnp_work/logs/                    datatrove's logging folder: completions/, logs/task_*.log, stats/
    ROOT/.pnp_work/shards/shard-00003/      rank 3's shard: a finalized LeRobotDataset (written as .tmp, renamed)
    ROOT/.pnp_work/progress/00003           episodes rank 3 has written so far (for the progress bar)
    ROOT/.pnp_work/merged/                  the aggregate being built

A root without ``.pnp_work`` holds a complete dataset. Only the entries a dataset consists of
(``DATASET_ENTRIES``) and the work folder are ever deleted: ``--overwrite`` and ``--resume`` keep the user's
own files. The lock is an ``flock`` on the root directory itself, taken before anything is deleted, and the
root directory is never removed, so ``--overwrite`` cannot pull a folder from under a running generation.
"""

from __future__ import annotations

import errno
import fcntl
import os
import shutil
import time
from pathlib import Path

from lerobot_pnp.dataset.layout import is_dataset, read_json
from lerobot_pnp.dataset.validation import WORK_DIR
from lerobot_pnp.errors import DatasetError

TRASH_DIR = ".pnp_work.trash"
DATASET_ENTRIES = ("meta", "data", "videos")  # what LeRobot writes into a dataset root
COMMIT_WAIT_S = 60.0  # how long a generation waits for a holder whose dataset is committed to let go
LOCK_FILE = ".pnp_lock"  # only where a directory cannot be flock-ed (NFS); never deleted while in use
RUN_FILE = "run.json"  # in the work folder: the settings of the run (``GenerateConfig.run_record``)
# The fields of a run record and their JSON types: what a resume compares and the shard layout it continues
RUN_FIELDS: dict[str, type | tuple[type, ...]] = {
    "repo_id": str,
    "seed": int,
    "num_episodes": int,
    "max_retries": int,
    "train_fraction": (int, float),
    "env": dict,
    "tasks": int,
}


def disk_error(root: Path, err: OSError) -> DatasetError:
    """One line for an operational write failure (full disk, read-only or missing permissions)."""
    what = {
        errno.ENOSPC: "the disk is full",
        errno.EDQUOT: "the disk quota is exceeded",
        errno.EFBIG: "a file size limit was reached",
        errno.EROFS: "the file system is read-only",
        errno.EACCES: "permission denied",
        errno.EPERM: "operation not permitted",
    }.get(err.errno, err.strerror or str(err))
    return DatasetError(
        f"cannot write the dataset in {root}: {what} ({err.filename or root}); the finished shards are kept: "
        "free space or fix permissions, then rerun the same command with --resume"
    )


def _busy(root: Path) -> DatasetError:
    return DatasetError(
        f"another `lerobot-pnp generate` is writing {root}; wait for it to finish (or stop it) "
        "before --resume or --overwrite"
    )


class RootLock:
    """An exclusive, non-blocking ``flock`` on the root directory (released when the process dies).

    ``busy`` is the one-line message when another process holds it (default: a generation's)."""

    def __init__(self, root: Path, busy: str | None = None):
        self.root, self.busy = root, busy
        try:
            root.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise disk_error(root, err) from None
        if not root.is_dir():
            raise DatasetError(f"{root} is a file, not a dataset folder")
        self.fd = os.open(root, os.O_RDONLY | os.O_DIRECTORY)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            os.close(self.fd)
            self.fd = None
            if err.errno not in (errno.EAGAIN, errno.EACCES):
                # e.g. NFS, where flock is emulated with POSIX locks that need a writable descriptor
                self._lock_file(root)
                return
            raise self._busy() from None

    def _lock_file(self, root: Path) -> None:
        self.fd = os.open(root / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.lockf(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            self.fd = None
            raise self._busy() from None

    def _busy(self) -> DatasetError:
        return DatasetError(self.busy) if self.busy else _busy(self.root)

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing the last descriptor releases the flock
            self.fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def generation_lock(root: Path) -> RootLock:
    """The root's lock for a generation. A holder whose run is committed (the dataset in place, no work folder)
    is finishing: the work folder's removal is the sign that a run is done, and the lock goes a moment later,
    when the committing process (the SLURM merge job) gets to release it. The command that follows that sign
    waits up to ``COMMIT_WAIT_S`` for the lock; a holder with a work folder is refused at once."""
    deadline = time.monotonic() + COMMIT_WAIT_S
    while True:
        try:
            return RootLock(root)
        except DatasetError:
            committed = not (root / WORK_DIR).exists() and is_dataset(root)
            if not committed or time.monotonic() >= deadline:
                raise
        time.sleep(0.05)


def root_state(root: Path) -> str:
    """empty | interrupted (a work folder) | complete (a dataset) | foreign (other files only)."""
    entries = {p.name for p in root.iterdir()} - {TRASH_DIR, LOCK_FILE}
    if WORK_DIR in entries:
        return "interrupted"
    if is_dataset(root):
        return "complete"
    return "foreign" if entries else "empty"


def remove_generation(root: Path) -> None:
    """Delete what a generation wrote into ``root`` (dataset entries and work folder); keep other files."""
    for name in (WORK_DIR, TRASH_DIR, *DATASET_ENTRIES):
        path = root / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists() or path.is_symlink():
            path.unlink()


def remove_partial_commit(root: Path) -> None:
    """Before a resumed merge: drop dataset entries a killed commit had started moving into ``root``."""
    for name in DATASET_ENTRIES:
        if (root / name).is_dir():
            shutil.rmtree(root / name)
    if (root / TRASH_DIR).exists():
        shutil.rmtree(root / TRASH_DIR)


def read_run_record(work: Path) -> dict:
    """The settings of the interrupted run in ``work`` (``run.json``), checked field by field before anything
    is read, deleted or run by them: a damaged or hand-edited record is refused in one line naming the field."""
    path = Path(work) / RUN_FILE
    run = read_json(path, "generation settings")
    why = _run_record_problem(run)
    if why is not None:
        raise DatasetError(
            f"{path} is not a generation record this package wrote ({why}); restore it, or start over with --overwrite"
        )
    return run


def _run_record_problem(run) -> str | None:
    if not isinstance(run, dict):
        return f"expected a JSON object, got {type(run).__name__}"
    for field, kind in RUN_FIELDS.items():
        if field not in run:
            return f"{field!r} is missing"
        if isinstance(run[field], bool) or not isinstance(run[field], kind):
            return f"{field} {run[field]!r} is not of type {getattr(kind, '__name__', 'number')}"
    if run["num_episodes"] < 1 or run["seed"] < 0 or run["max_retries"] < 0:
        return "num_episodes must be >= 1, seed and max_retries >= 0"
    if not 1 <= run["tasks"] <= run["num_episodes"]:
        return f"tasks {run['tasks']} is not in [1, num_episodes {run['num_episodes']}]"
    if not 0 < run["train_fraction"] <= 1:
        return f"train_fraction {run['train_fraction']} is not in (0, 1]"
    return None


def episodes_recorded(work: Path) -> bool:
    """Whether the run in ``work`` wrote an episode: a rank counted one (``progress/``) or finished its shard."""
    work = Path(work)
    for path in (work / "progress").glob("*"):
        try:
            if int(path.read_text().split()[0]) > 0:
                return True
        except (OSError, ValueError, IndexError):
            return True  # unreadable: assume there is work worth keeping
    return any(not p.name.endswith(".tmp") for p in (work / "shards").glob("shard-*"))
