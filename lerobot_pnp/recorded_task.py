"""The recorded task: the env config a dataset was generated in, or a checkpoint was trained in, as a JSON file.

A dataset folder holds it in ``meta/baxter_pnp_env.json`` (``recorded_files.write_recorded``), a checkpoint's
``pretrained_model`` folder in ``baxter_pnp_env.json`` (``write_checkpoint_task``, ``copy_recorded``). Whoever
replays, trains on or evaluates the data reads it back (``read_recorded``; the env config's ``task_source``).
A record is validated wherever it is read or copied, by one rule (``check_recorded``: ``recorded_files.check_record``
with the env config): a JSON object of this env's type, no field the env config does not know (a newer version's
record, or a hand edit, is refused naming the fields, not half-read), every number finite, the whole a valid
config. The env config itself reads records through ``recorded_files``; this module imports it only when a
record is checked.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from lerobot_pnp.recorded_files import (
    CHECKPOINT_RECORDED_FILE,
    RECORDED_FILE,
    check_record,
    find_recorded,
    read_json,
)


def check_recorded(data: Any, path: str | Path) -> dict:
    """A recorded task, validated against ``BaxterPnPEnvConfig`` (``recorded_files.check_record``): the one rule
    of every reader and copier."""
    return check_record(data, path, _config_class())


def _config_class():
    """``BaxterPnPEnvConfig`` (imported when a record is checked: importing this module stays cheap)."""
    from lerobot_pnp.env_config import BaxterPnPEnvConfig

    return BaxterPnPEnvConfig


def dataset_task(dataset_root: str | Path) -> dict | None:
    """The task recorded with a dataset folder, validated; None when it records none."""
    source = Path(dataset_root) / RECORDED_FILE
    return check_recorded(read_json(source), source) if source.is_file() else None


def write_checkpoint_task(task: dict, directory: str | Path) -> Path:
    """Record ``task`` in a checkpoint's ``pretrained_model`` folder (``baxter_pnp_env.json``)."""
    path = Path(directory) / CHECKPOINT_RECORDED_FILE
    path.write_text(json.dumps(check_recorded(task, path), indent=2))
    return path


def copy_recorded(dataset_root: str | Path, directory: str | Path) -> Path:
    """Copy a dataset's recorded task into a checkpoint folder, validated first (a bad one is not copied)."""
    source = Path(dataset_root) / RECORDED_FILE
    return write_checkpoint_task(check_recorded(read_json(source), source), directory)


def read_recorded(source: str | Path) -> dict | None:
    """The env config recorded with a dataset folder, or with the dataset a checkpoint was trained on, validated.

    ``source`` is a dataset root, a checkpoint's ``pretrained_model`` folder, or a training output folder.
    Returns None when nothing is recorded there.
    """
    found = find_recorded(source)
    return check_recorded(*found) if found is not None else None
