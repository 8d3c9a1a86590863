"""The output folder of a training run, through the one owner of output folders (``lerobot_pnp.outputs``).

A run holds the folder (``OutputFolder``: its lock) from start to end, so two runs into one folder cannot leave
their checkpoints side by side under a config that names one of them. Every entry it writes is recorded in the
folder's manifest before it is written, and ``--overwrite`` deletes exactly the entries a training run recorded
there, never anything else: a folder holding an entry a training run did not write is refused in one line before
any work starts. A run folder written before manifests existed (nothing but a training run's files, its
``train_fast_config.json`` among them) counts as a training run's.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from lerobot_pnp.outputs import HOUSEKEEPING, NEW_SUFFIX, TMP_SUFFIX, OutputError, OutputFolder, remove_path

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
    """The entries of a run folder that predates the manifest: every entry a training run's file, its config among
    them, and nothing recorded yet; else none."""
    names = _present(folder.path)
    if folder.owners or CONFIG_FILE not in names or any(n not in RUN_FILES for n in names):
        return []
    return names


def _check(folder: OutputFolder, overwrite: bool) -> None:
    """Refuse (``OutputError``, one line) a folder holding a run without ``overwrite``, and one holding an entry
    a training run did not write."""
    present = _present(folder.path)
    if not present:
        return
    ours = folder.entries | set(legacy_run(folder))
    foreign = sorted((name for name in present if name not in ours), key=lambda name: name in RUN_FILES)
    out = folder.path
    if not overwrite:
        why = (
            f" ({out / foreign[0]} is not a training run's file)"
            if foreign
            else " or pass --overwrite (the run is replaced)"
        )
        raise OutputError(f"output_dir {out} already exists and is not empty; choose another folder{why}")
    if foreign:
        raise OutputError(
            f"--overwrite: output_dir {out} holds {out / foreign[0]}, which `{COMMAND}` did not write "
            f"({len(foreign)} such entr{'y' if len(foreign) == 1 else 'ies'}); --overwrite replaces only what a "
            "training run wrote: move it or choose another folder"
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
