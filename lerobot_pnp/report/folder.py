"""The study's output folder, through the one owner of output folders (``outputs.OutputFolder``).

``report`` and ``demo`` run the same study and own its entries under one name (``COMMAND``) in the folder's
``.pnp_manifest.json``. Before a study writes anything, every top-level name it will write (``study_names``)
is checked: an entry of that name that the study did not write (a user's dataset, a ``train/`` of
``lerobot-train`` runs) stops the run in one line with nothing written, so the study never writes into, reuses,
replaces or (``--fresh``) deletes what is not its own. ``--fresh`` deletes the entries the study wrote; the
user's stay. A study folder written before manifests is recognised by what its entries hold
(``stages.written_by_the_study``) and those entries are recorded as the study's.
"""

from __future__ import annotations

from pathlib import Path

from lerobot_pnp.errors import PnPError
from lerobot_pnp.outputs import MANIFEST_FILE, OutputError, OutputFolder, shown
from lerobot_pnp.report.layout import StudyLayout
from lerobot_pnp.report.methods import get_methods
from lerobot_pnp.report.stages import written_by_the_study

COMMAND = "lerobot-pnp report/demo"  # the owner of a study's entries in its folder's manifest


class StudyInterrupted(PnPError):
    """A study stopped by Ctrl-C or SIGTERM: what it finished is kept, and the same command continues it."""


def interrupted(out: Path) -> StudyInterrupted:
    """The one line for an interrupted study: rerunning the same command resumes it (every finished stage is
    reused by its key; the dataset generation finishes where it stopped; an unfinished training or evaluation
    starts over)."""
    return StudyInterrupted(
        f"interrupted; what the study finished in {shown(out)} is kept: run the same command again to continue "
        "(finished stages are reused, an unfinished one starts over; --fresh true starts the whole study over)"
    )


def open_study_folder(out: Path) -> OutputFolder:
    """The study folder, locked (a second command on it fails at once, in one line); in a study folder written
    before manifests, the entries provably the study's are recorded as its own."""
    folder = OutputFolder(out, COMMAND)
    try:
        older = not (folder.path / MANIFEST_FILE).exists() and StudyLayout(folder.path).config.is_file()
        if older and (entries := [p.name for p in folder.path.iterdir() if written_by_the_study(p)]):
            folder.adopt(*entries)
    except BaseException:
        folder.close()
        raise
    return folder


def study_names(cfg, layout: StudyLayout) -> tuple[str, ...]:
    """Every top-level entry the study of ``cfg`` writes in its folder."""
    recordings = [m.data for m in get_methods(cfg.methods)]
    return layout.names(recordings, cluster=cfg.executor == "slurm")


def refuse_taken(folder: OutputFolder, names: tuple[str, ...]) -> None:
    """Refuse (one line, nothing written) when an entry the study would write is in the folder and is not the
    study's: it was there before (the user's, or another command's); a link is refused too (``entry``)."""
    taken = [n for n in names if not folder.owns(n) and (folder.entry(n).exists() or folder.entry(n).is_symlink())]
    if not taken:
        return
    listed = ", ".join(taken)
    raise OutputError(
        f"{shown(folder.path)} already holds {listed}, which the study did not write and would write into; it "
        f"replaces only what it wrote: move {'it' if len(taken) == 1 else 'them'} or choose another --output_dir"
    )
