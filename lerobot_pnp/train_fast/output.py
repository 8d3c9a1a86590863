"""The output folder of a training run: locked for the run, replaced whole by ``--overwrite``.

Two runs into one folder would otherwise both succeed and leave their checkpoints side by side under a config
that names only one of them, and an overwritten run would keep its stale checkpoints beside the new ones. So a
run holds the folder's lock (``cache.lock_output``, the generation's ``RootLock``) from start to end, and
``--overwrite`` deletes exactly the files a training run writes there, never anything else: a folder that holds
another file is refused in one line before any work starts.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from lerobot_pnp.cache import lock_output, remove
from lerobot_pnp.errors import ConfigError

COMMAND = "lerobot-pnp train"
# The top-level entries of a training run's folder (the package docstring lists what each holds).
RUN_FILES = ("checkpoints", "train_fast_config.json", "loss_curve.csv", "loss_curve.png", "test_keyframe_error.json")


def _lock_file() -> str:
    from lerobot_pnp.dataset.workdir import LOCK_FILE

    return LOCK_FILE


def check_output(out: Path, overwrite: bool) -> None:
    """Refuse (``ConfigError``, one line) an output folder that is a file, one that holds a run without
    ``overwrite``, and one that holds anything a training run does not write."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"output_dir {out} exists and is not a folder")
    entries = sorted(p.name for p in out.iterdir() if p.name != _lock_file()) if out.is_dir() else []
    if not entries:
        return
    foreign = [name for name in entries if name not in RUN_FILES]
    if not overwrite:
        why = (
            f" ({out / foreign[0]} is not a training run's file)"
            if foreign
            else " or pass --overwrite (the run is replaced)"
        )
        raise ConfigError(f"output_dir {out} already exists and is not empty; choose another folder{why}")
    if foreign:
        raise ConfigError(
            f"--overwrite: output_dir {out} holds {out / foreign[0]}, which `{COMMAND}` did not write "
            f"({len(foreign)} such entr{'y' if len(foreign) == 1 else 'ies'}); --overwrite replaces only a training "
            f"run's files ({', '.join(RUN_FILES)}): move it or choose another folder"
        )


@contextmanager
def locked_output(out: Path, overwrite: bool) -> Iterator[None]:
    """Hold ``out``'s lock for the run and check the folder again under it (another process may have written
    there since the config was checked); a run that fails before writing anything leaves no new folder."""
    out = Path(out)
    existed = out.exists()
    with lock_output(out, COMMAND):
        check_output(out, overwrite)
        try:
            yield
        except BaseException:
            if not existed and not any(p.name != _lock_file() for p in out.iterdir()):
                remove(out)
            raise


def clear_previous_run(out: Path) -> None:
    """Delete a previous run's files from ``out`` (the caller holds the lock and has checked the folder);
    a link among them is removed, never followed."""
    for name in RUN_FILES:
        remove(Path(out) / name)
