"""The expert's FSM phases as LeRobot subtask annotations (``lerobot-pnp generate --subtask_annotations true``).

LeRobot 0.6.1 stores language annotations in two columns of the data files, ``language_persistent`` (styles
``subtask``, ``plan``, ``memory``, ...: rows that hold from their timestamp until superseded, broadcast to every
frame of the episode) and ``language_events``. Its annotation pipeline (``lerobot-annotate``) asks a VLM for the
subtask spans; here they are known exactly: one ``subtask`` row, stamped at the frame where the phase starts,
for each run of equal ``phase.index`` (a recovery that goes back to an earlier phase opens a new span). The rows
are written with LeRobot's own staging and writer (``EpisodeStaging``, ``LanguageColumnsWriter``) and the two
columns are declared in ``meta/info.json`` as its pipeline does, so LeRobot's loader, ``lerobot-annotate``'s
consumers and annotation-aware policies read them.

Opt-in: the columns change the data files, and the ``paper`` dataset's content hash is fixed by a test.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import DatasetError

PHASE_COLUMN = "phase.index"


def subtask_rows(timestamps: np.ndarray, phases: np.ndarray) -> list[dict]:
    """``subtask`` rows of one episode: one per run of equal phase, at the run's first frame."""
    starts = np.flatnonzero(np.r_[True, phases[1:] != phases[:-1]]) if len(phases) else []
    return [
        {
            "role": "assistant",
            "content": robot.Phase(int(phases[i])).label,
            "style": "subtask",
            "timestamp": float(timestamps[i]),
            "camera": None,
            "tool_calls": None,
        }
        for i in starts
    ]


def annotate_subtasks(root: str | Path) -> int:
    """Write the FSM phases of every episode of the dataset in ``root`` as subtask rows; returns the row count.

    Idempotent (LeRobot's writer replaces existing language columns). Each data file is replaced atomically.
    """
    import pyarrow.parquet as pq
    from lerobot.annotations.steerable_pipeline.reader import iter_episodes
    from lerobot.annotations.steerable_pipeline.staging import EpisodeStaging
    from lerobot.annotations.steerable_pipeline.writer import LanguageColumnsWriter
    from lerobot.datasets.io_utils import load_info, write_info
    from lerobot.datasets.language import language_feature_info

    root = Path(root)
    if PHASE_COLUMN not in load_info(root).features:
        raise DatasetError(f"{root}: no {PHASE_COLUMN!r} feature, so there are no FSM phases to annotate")
    records = list(iter_episodes(root))
    n_rows = 0
    with tempfile.TemporaryDirectory(prefix=".pnp_annotations_", dir=root) as staging_dir:
        tables: dict[Path, object] = {}
        for record in records:
            if record.data_path not in tables:
                tables[record.data_path] = pq.read_table(record.data_path, columns=["timestamp", PHASE_COLUMN])
            table = tables[record.data_path]
            span = slice(record.row_offset, record.row_offset + record.row_count)
            ts = table.column("timestamp").to_numpy()[span]
            phases = np.asarray(table.column(PHASE_COLUMN).to_pylist()[span.start : span.stop]).reshape(-1)
            rows = subtask_rows(ts, phases)
            EpisodeStaging(Path(staging_dir), record.episode_index).write("plan", rows)
            n_rows += len(rows)
        LanguageColumnsWriter(drop_existing_subtask_index=False).write_all(records, Path(staging_dir), root)
    info = load_info(root)
    info.features = {**info.features, **language_feature_info()}
    write_info(info, root)
    return n_rows
