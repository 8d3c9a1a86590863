"""The output folder of a training run, through the one owner of output folders (``lerobot_pnp.outputs``).

A run holds the folder (``OutputFolder``: its lock) from start to end, so two runs into one folder cannot leave
their checkpoints side by side under a config that names one of them. Every entry it writes is recorded in the
folder's manifest before it is written, and ``--overwrite`` deletes exactly the entries a training run recorded
there: a user's file beside them stays, and a user's entry under a name a run writes is refused in one line
before any work starts. In a run folder written before manifests existed (its ``train_fast_config.json`` there,
nothing recorded) the entries with a training run's names count as the run's.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from lerobot_pnp.outputs import (
    HOUSEKEEPING,
    NEW_SUFFIX,
    TMP_SUFFIX,
    OutputError,
    OutputFolder,
    read_record,
    remove_path,
)

COMMAND = "lerobot-pnp train"
CONFIG_FILE = "train_fast_config.json"
# The top-level entries of a training run's folder (the package docstring lists what each holds).
RUN_FILES = ("checkpoints", CONFIG_FILE, "loss_curve.csv", "loss_curve.png", "test_keyframe_error.json")


def _present(folder: Path) -> list[str]:
    """The entries of ``folder`` besides the owner's housekeeping files."""
    return sorted(
        p.name
        for p in folder.iterdir()
        if p.name not in HOUSEKEEPING and p.name.removesuffix(TMP_SUFFIX).removesuffix(NEW_SUFFIX) not in HOUSEKEEPING
    )


def legacy_run(folder: OutputFolder) -> list[str]:
    """The training run's entries in a folder that predates the manifest: nothing is recorded there and the run's
    config file is (``_is_run_config``); then every entry with a training run's name (a user's file beside them
    is not among them)."""
    if folder.owners or not _is_run_config(folder.path / CONFIG_FILE):
        return []
    return [name for name in _present(folder.path) if name in RUN_FILES]


def _is_run_config(path: Path) -> bool:
    """Whether ``path`` is a config file a training run wrote: a plain file holding a mapping with the keys
    every ``TrainFastConfig`` has."""
    data = read_record(path)
    return isinstance(data, dict) and {"dataset_repo_id", "policy", "output_dir"} <= set(data)


def _check(folder: OutputFolder, overwrite: bool) -> None:
    """Refuse (``OutputError``, one line) an entry a training run did not write under a name a run writes, and a
    previous run without ``overwrite``. A user's other files stay beside the run."""
    present = _present(folder.path)
    ours = folder.entries | set(legacy_run(folder))
    out = folder.path
    if blocking := [name for name in present if name in RUN_FILES and name not in ours]:
        raise OutputError(
            f"output_dir {out} holds {out / blocking[0]}, which `{COMMAND}` did not write and a training run "
            f"writes ({', '.join(RUN_FILES)}); move it or choose another folder"
        )
    if not overwrite and any(name in ours for name in present):
        raise OutputError(
            f"output_dir {out} already holds a training run; choose another folder or pass --overwrite (the run "
            "is replaced; other files stay)"
        )


def check_output(out: Path, overwrite: bool) -> None:
    """The checks of ``run_folder``, without taking the folder (a config is checked before any work)."""
    out = Path(out).expanduser()
    if out.exists() and not out.is_dir():
        raise OutputError(f"output_dir {out} exists and is not a folder")
    if out.is_dir():
        with OutputFolder(out, COMMAND, lock=False) as folder:
            _check(folder, overwrite)


@contextmanager
def run_folder(out: Path, overwrite: bool) -> Iterator[OutputFolder]:
    """Hold ``out`` for the run and check it again under its lock (another process may have written there since
    the config was checked); a run that fails before writing anything leaves no new folder."""
    out = Path(out)
    existed = out.exists()
    with OutputFolder(out, COMMAND) as folder:
        _check(folder, overwrite)
        try:
            yield folder
        except BaseException:
            if not existed and not _present(out):
                remove_path(out)  # made by this run, which wrote nothing in it
            raise


def clear_previous_run(folder: OutputFolder) -> None:
    """Delete what a previous training run wrote in the folder (recorded, or a run from before the manifest);
    the caller has checked that nothing else is there. A link among them is removed, never followed."""
    if legacy := legacy_run(folder):
        folder.adopt(*legacy)
    folder.clear()
