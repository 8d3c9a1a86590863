"""Where a dataset folder keeps what describes it, and the one reader of its JSON files.

The paths are LeRobot's (``meta/info.json``, LeRobot's ``INFO_PATH``) and ours (``meta/baxter_pnp_env.json``,
``recorded_files.RECORDED_FILE``, and the generation record ``meta/pnp_generate.json``,
``recorded_files.GENERATION_FILE``); every module asks here instead of joining the path itself.
"""

from __future__ import annotations

import json
from pathlib import Path

from lerobot_pnp.errors import DatasetError
from lerobot_pnp.recorded_files import RECORDED_FILE

INFO_FILE = "meta/info.json"  # LeRobot's INFO_PATH: the dataset's metadata, with its "splits"


def read_json(path: Path, what: str) -> dict:
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise DatasetError(f"{what} missing: {path}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise DatasetError(f"{what} is corrupt ({path}): {err}") from None


def info_path(root: str | Path) -> Path:
    """``meta/info.json`` of the dataset folder ``root``."""
    return Path(root) / INFO_FILE


def read_info(root: str | Path) -> dict:
    """``meta/info.json`` as a dict (DatasetError when it is missing or corrupt)."""
    return read_json(info_path(root), INFO_FILE)


def is_dataset(root: str | Path) -> bool:
    """Whether ``root`` holds a (finalized) LeRobot dataset: it has a ``meta/info.json``."""
    return info_path(Path(root).expanduser()).is_file()


def recorded_task_path(root: str | Path) -> Path:
    """The task a dataset was recorded in (``meta/baxter_pnp_env.json``, written by ``write_recorded``)."""
    return Path(root) / RECORDED_FILE
