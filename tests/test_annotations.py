"""The FSM phases as LeRobot subtask annotations (``generate --subtask_annotations true``): opt-in, read by
LeRobot's own loader, one span per run of equal phase, and the other columns untouched."""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest

from lerobot_pnp import robot
from lerobot_pnp.dataset import GenerateConfig, generate, validate_dataset
from lerobot_pnp.dataset.annotations import subtask_rows
from lerobot_pnp.errors import ConfigError


def _gen(root, **kw):
    cfg = GenerateConfig(repo_id="local/ann", root=str(root), num_episodes=2, workers=1, progress=False, **kw)
    return generate(cfg)


def _table(root):
    return pq.read_table(sorted((root / "data").rglob("*.parquet"))[0])


def test_subtask_rows_one_per_phase_run():
    rows = subtask_rows(np.array([0.0, 0.05, 0.1, 0.15, 0.2]), np.array([0, 0, 1, 0, 0]))
    assert [(r["content"], r["timestamp"]) for r in rows] == [
        (robot.PHASE_NAMES[0], 0.0),
        (robot.PHASE_NAMES[1], 0.1),
        (robot.PHASE_NAMES[0], 0.15),  # a recovery back to an earlier phase opens a new span
    ]
    assert all(r["style"] == "subtask" and r["role"] == "assistant" for r in rows)


def test_annotations_opt_in_readable_by_lerobot(tmp_path):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    plain, annotated = tmp_path / "plain", tmp_path / "ann"
    _gen(plain)
    summary = _gen(annotated, subtask_annotations=True)
    assert "language_persistent" not in _table(plain).column_names  # off by default: data files unchanged
    assert summary["subtask_rows"] == 2 * robot.N_KEYFRAMES  # the expert visits each of the 10 phases once
    validate_dataset(annotated)

    a, p = _table(annotated), _table(plain)
    assert a.drop_columns(["language_persistent", "language_events"]).equals(p)  # only the columns are added
    ds = LeRobotDataset("local/ann", root=annotated, video_backend="pyav")
    assert {"language_persistent", "language_events"} <= set(ds.meta.features)
    item = ds[robot.N_KEYFRAMES + 3]  # episode 1, frame 3: the persistent rows hold the whole episode's spans
    spans = [(r["content"], r["timestamp"]) for r in item["language_persistent"]]
    assert spans == [(name, float(i)) for i, name in enumerate(robot.PHASE_NAMES)]
    assert int(item["phase.index"]) == 3


def test_annotations_not_with_slurm():
    with pytest.raises(ConfigError, match="subtask_annotations"):
        GenerateConfig(executor="slurm", subtask_annotations=True)
