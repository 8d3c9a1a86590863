"""The output root of a generation: its layout, its owner and lock, and what may be deleted in it.

While a run is in progress the root holds a work folder (and whatever unrelated files the user keeps there)::

    ROOT/.pnp_work/run.json                 the generation settings and the resolved env config of the run
    ROOT/.pnp_work/logs/                    datatrove's logging folder: completions/, logs/task_*.log, stats/
    ROOT/.pnp_work/shards/shard-00003/      rank 3's shard: a finalized LeRobotDataset (written as .tmp, renamed)
    ROOT/.pnp_work/progress/00003           episodes rank 3 has written so far (for the progress bar)
    ROOT/.pnp_work/merged/                  the aggregate being built
    ROOT/.pnp_work/replaced/                the previous dataset's entries, moved aside by the commit

A root without ``.pnp_work`` holds a complete dataset. The root is the output folder (``lerobot_pnp.outputs``)
of ``lerobot-pnp generate``: the entries a generation writes (``GENERATE_ENTRIES``) are claimed in the root's
manifest before they are written, and only those are ever replaced or deleted: ``--overwrite`` and ``--resume``
keep the user's own files. A dataset written before manifests existed is proven by the two files only a
generation writes (``LEGACY_MARKER``), a work folder by holding only what a run writes there; both are adopted.
A symbolic link among these entries, or anywhere in a work folder a run continues, is refused in one line: it
is never followed, and never deleted. The previous dataset stays in place until the new one is committed in its
place. The lock is an ``flock`` on the root directory itself, taken before anything is read or deleted, and the
root directory is never removed while it holds anything, so ``--overwrite`` cannot pull a folder from under a
running generation.
"""

from __future__ import annotations

import errno
import os
import time
from pathlib import Path

from lerobot_pnp.dataset.layout import is_dataset, read_json, recorded_task_path
from lerobot_pnp.dataset.validation import WORK_DIR
from lerobot_pnp.errors import DatasetError
from lerobot_pnp.outputs import (
    HOUSEKEEPING,
    TMP_SUFFIX,
    FolderLock,
    OutputError,
    OutputFolder,
    remove_path,
    shown,
)
from lerobot_pnp.outputs import LOCK_FILE as LOCK_FILE  # the lock file, named here for the modules that ask here
from lerobot_pnp.recorded_files import GENERATION_FILE

COMMAND = "lerobot-pnp generate"  # the owner's name in the root's manifest
TRASH_DIR = ".pnp_work.trash"  # a committed run's work folder, being deleted
REPLACED_DIR = "replaced"  # in the work folder: the entries of the dataset a commit replaces
DATASET_ENTRIES = ("meta", "data", "videos", "images")  # what LeRobot writes into a dataset root (images: left empty)
GENERATE_ENTRIES = (WORK_DIR, TRASH_DIR, *DATASET_ENTRIES)
COMMIT_WAIT_S = 60.0  # how long a generation waits for a holder whose dataset is committed to let go
RUN_FILE = "run.json"  # in the work folder: the settings of the run (``GenerateConfig.run_record``)
WORK_ENTRIES = frozenset({RUN_FILE, "logs", "shards", "progress", "merged", "slurm.json", REPLACED_DIR})
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


def resume_advice(overwrite: bool | None = None) -> str:
    """What finishes an interrupted generation: its command with --resume, which takes the place of --overwrite
    (the two flags are exclusive). ``None``: the command is not known here (a shard's worker)."""
    if overwrite is None:
        return "rerun the same command with --resume (in place of --overwrite, if it had one)"
    return f"rerun the same command with --resume{' in place of --overwrite' if overwrite else ''}"


def disk_error(root: Path, err: OSError, advice: str | None = None) -> DatasetError:
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
        f"free space or fix permissions, then {advice or resume_advice()}"
    )


def _busy(root: Path) -> DatasetError:
    return DatasetError(
        f"another `lerobot-pnp generate` is writing {root}; wait for it to finish (or stop it) "
        "before --resume or --overwrite"
    )


def generation_lock(root: Path) -> FolderLock:
    """The root's lock for a generation. A holder whose run is committed (the dataset in place, no work folder)
    is finishing: the work folder's removal is the sign that a run is done, and the lock goes a moment later,
    when the committing process (the SLURM merge job) gets to release it. The command that follows that sign
    waits up to ``COMMIT_WAIT_S`` for the lock; a holder with a work folder is refused at once."""
    deadline = time.monotonic() + COMMIT_WAIT_S
    while True:
        try:
            return FolderLock(root, str(_busy(root)), DatasetError)
        except DatasetError:
            committed = not (root / WORK_DIR).exists() and is_dataset(root)
            if not committed or time.monotonic() >= deadline:
                raise
        time.sleep(0.05)


def first_link(folder: Path) -> Path | None:
    """The first symbolic link anywhere under ``folder`` (links are listed, never entered), or None."""
    for top, dirs, files in os.walk(folder):
        for name in sorted(dirs + files):
            if os.path.islink(os.path.join(top, name)):
                return Path(top) / name
    return None


class DatasetRoot(OutputFolder):
    """A dataset root as the output folder of ``lerobot-pnp generate``, locked from construction to ``close``.

    Opening it refuses a link among ``GENERATE_ENTRIES``, adopts a dataset or work folder older than manifests
    (proven by the files only a generation writes), and deletes a committed run's leftover trash."""

    def __init__(self, root: Path):
        root = Path(root)
        if root.exists() and not root.is_dir():
            raise DatasetError(f"{root} is a file, not a dataset folder")
        try:
            root.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise disk_error(root, err) from None
        lock = generation_lock(root)
        try:
            super().__init__(root, COMMAND, flag="--root", lock=False)
            self.lock = lock
            for name in GENERATE_ENTRIES:
                self.entry(name)  # a link: one line naming it
            if not self.entries:
                self._adopt_legacy()
            if self.owns(TRASH_DIR):
                self.remove(TRASH_DIR)
        except BaseException:
            lock.close()
            raise

    def _adopt_legacy(self) -> None:
        """Record the entries a generation wrote before manifests existed: a work folder (or its trash) holding
        only what a run writes there, and the dataset entries beside a dataset whose ``meta`` holds both
        generation records or beside a work folder with its run record (a run started only in a root without
        other files, and replaced or committed what it found of these names)."""
        proven = []
        for name in (WORK_DIR, TRASH_DIR):
            path = self.path / name
            if path.is_dir() and {p.name for p in path.iterdir()} <= WORK_ENTRIES:
                proven.append(name)
        markers = (recorded_task_path(self.path), self.path / GENERATION_FILE)
        if WORK_DIR in proven and (self.path / WORK_DIR / RUN_FILE).is_file():
            markers = (self.path / WORK_DIR / RUN_FILE,)
        if all(p.is_file() and not p.is_symlink() for p in markers):
            proven += [name for name in DATASET_ENTRIES if (self.path / name).exists()]
        if proven:
            self.adopt(*proven)

    def state(self) -> str:
        """empty | interrupted (a work folder) | complete (a dataset) | foreign (only entries it did not write)."""
        names = {p.name for p in self.path.iterdir()}
        names = {n for n in names if n.removesuffix(TMP_SUFFIX) not in HOUSEKEEPING} - {TRASH_DIR}
        if WORK_DIR in names:
            return "interrupted"
        if is_dataset(self.path):
            return "complete"
        return "foreign" if names and not names & self.entries else "empty"

    def work(self) -> Path:
        """The work folder of the run being continued, refusing one with a symbolic link anywhere inside."""
        work = self.entry(WORK_DIR)
        link = first_link(work) if work.is_dir() else None
        if link is not None:
            raise OutputError(
                f"{shown(link)} is a symbolic link in the work folder; `{COMMAND}` never follows a link: remove "
                "it, or start over with --overwrite"
            )
        return work

    def commit(self, merged: Path) -> None:
        """Put the dataset built in ``merged`` in place of the root's: the previous dataset's entries are moved
        into the work folder, the new ones moved in, then the work folder goes (renamed to the trash first).
        Killed half-way, the work folder is still there and ``--resume`` merges and commits again."""
        names = sorted(p.name for p in merged.iterdir())
        entries = list(dict.fromkeys([*DATASET_ENTRIES, *names]))
        self.claim(*entries)  # an entry LeRobot wrote besides the usual ones is claimed before it is moved in
        replaced = self.work() / REPLACED_DIR
        replaced.mkdir(exist_ok=True)
        for name in entries:
            path = self.entry(name)
            if path.exists():
                remove_path(replaced / name)
                os.replace(path, replaced / name)
        for name in names:
            os.replace(merged / name, self.path / name)
        self.remove(TRASH_DIR)
        os.replace(self.path / WORK_DIR, self.path / TRASH_DIR)
        self.remove(TRASH_DIR)
        self.release()

    def release(self) -> None:
        """Forget the claims on entries that are not on disk (a run stopped before writing them, a committed
        run's work folder), and the manifest itself once no command has an entry left in it."""
        mine = self.owners.get(COMMAND, set())
        here = {name for name in mine if (self.path / name).exists() or (self.path / name).is_symlink()}
        if here != mine:
            self.owners[COMMAND] = here
            self._write_manifest()
        if not any(self.owners.values()):
            remove_path(self.manifest)


def remove_generation(root: Path) -> None:
    """Delete what a generation wrote into ``root`` (its dataset and work folder); the user's files stay. An
    entry of those names that it cannot prove it wrote is refused (one line) before anything is deleted."""
    with DatasetRoot(root) as out:
        present = [n for n in GENERATE_ENTRIES if (out.path / n).exists()]
        out.claim(*present)
        for name in present:
            out.remove(name)
        out.release()


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
