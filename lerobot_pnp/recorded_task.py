"""The recorded task: the env config a dataset was generated in, or a checkpoint was trained in, as a JSON file.

A dataset folder holds it in ``meta/baxter_pnp_env.json`` (``write_recorded``), a checkpoint's
``pretrained_model`` folder in ``baxter_pnp_env.json`` (``write_checkpoint_task``, ``copy_recorded``). Whoever
replays, trains on or evaluates the data reads it back (``read_recorded``; the env config's ``task_source``).
A record is validated wherever it is read or copied, by one rule (``check_recorded``): a JSON object of this
env's type, no field the env config does not know (a newer version's record, or a hand edit, is refused naming
the fields, not half-read), every number finite, the whole a valid config. ``env_config`` reads records through
this module, which imports it only when a record is checked.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import fields
from pathlib import Path
from typing import Any

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.presets import ENV_TYPE

RECORDED_FILE = "meta/baxter_pnp_env.json"  # in a dataset folder
CHECKPOINT_RECORDED_FILE = "baxter_pnp_env.json"  # the task a checkpoint was trained in, in pretrained_model/
# Fields a record may hold that the env config no longer has: ignored when read (a field's removal must be listed
# here, or every dataset recorded before it would be refused as unknown)
RETIRED_FIELDS: frozenset[str] = frozenset()


def write_recorded(config: Any, root: str | Path) -> Path:
    """Record ``config`` (a ``BaxterPnPEnvConfig``) in a dataset folder (``meta/baxter_pnp_env.json``)."""
    path = Path(root) / RECORDED_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps({"type": ENV_TYPE, **config.to_dict()}, indent=2))
    tmp.replace(path)
    return path


def check_recorded(data: Any, path: str | Path) -> dict:
    """A recorded task, validated: a JSON object of this env's type, every key a field of the env config (or
    one of ``RETIRED_FIELDS``, dropped), every number finite, the whole a valid config (a contradictory, corrupt
    or unknown record is one ConfigError naming the file). The one rule of every reader and copier."""
    if not isinstance(data, dict) or data.get("type", ENV_TYPE) != ENV_TYPE:
        raise ConfigError(f"the recorded env config {path} is not a {ENV_TYPE} env config")
    config_cls = _config_class()
    valid = {f.name for f in fields(config_cls)}  # features / features_map: in a train_config's env, derived
    unknown = sorted(set(data) - valid - RETIRED_FIELDS - {"type"})
    if unknown:
        from lerobot_pnp import __version__

        raise ConfigError(
            f"the recorded env config {path} has field(s) {unknown} that lerobot_pnp {__version__} does not know: "
            f"a newer lerobot_pnp wrote it (upgrade this one to read it) or it was edited by hand; valid fields: "
            f"{sorted(valid)}"
        )
    data = {k: v for k, v in data.items() if k not in RETIRED_FIELDS}
    bad = sorted(k for k, v in data.items() if _not_finite(v))
    if bad:
        raise ConfigError(f"the recorded env config {path} has non-finite values in {bad}")
    try:
        config_cls.from_dict({k: v for k, v in data.items() if k != "type"} | {"preset": data.get("preset") or "paper"})
    except (ConfigError, TypeError) as err:
        raise ConfigError(f"the recorded env config {path} is invalid: {err}") from None
    return data


def _config_class():
    """``BaxterPnPEnvConfig`` (imported here: ``env_config`` reads records through this module)."""
    from lerobot_pnp.env_config import BaxterPnPEnvConfig

    return BaxterPnPEnvConfig


def _not_finite(value: Any) -> bool:
    if isinstance(value, float):
        return not math.isfinite(value)
    return isinstance(value, list | tuple) and any(_not_finite(v) for v in value)


def dataset_task(dataset_root: str | Path) -> dict | None:
    """The task recorded with a dataset folder, validated; None when it records none."""
    source = Path(dataset_root) / RECORDED_FILE
    return check_recorded(_read_json(source), source) if source.is_file() else None


def write_checkpoint_task(task: dict, directory: str | Path) -> Path:
    """Record ``task`` in a checkpoint's ``pretrained_model`` folder (``baxter_pnp_env.json``)."""
    path = Path(directory) / CHECKPOINT_RECORDED_FILE
    path.write_text(json.dumps(check_recorded(task, path), indent=2))
    return path


def copy_recorded(dataset_root: str | Path, directory: str | Path) -> Path:
    """Copy a dataset's recorded task into a checkpoint folder, validated first (a bad one is not copied)."""
    source = Path(dataset_root) / RECORDED_FILE
    return write_checkpoint_task(check_recorded(_read_json(source), source), directory)


def read_recorded(source: str | Path) -> dict | None:
    """The env config recorded with a dataset folder, or with the dataset a checkpoint was trained on.

    ``source`` is a dataset root, a checkpoint's ``pretrained_model`` folder, or a training output folder.
    Returns None when nothing is recorded there.
    """
    source = Path(source).expanduser()
    candidates = [source / RECORDED_FILE, source / CHECKPOINT_RECORDED_FILE]
    for path in candidates:
        if path.is_file():
            return check_recorded(_read_json(path), path)
    for train_cfg in (source / "train_config.json", source / "checkpoints/last/pretrained_model/train_config.json"):
        if train_cfg.is_file():
            # the env the training resolved when it started comes first: the dataset root may hold another
            # task by now (regenerated since)
            env = _read_json(train_cfg).get("env") or {}
            if env.get("type") == ENV_TYPE:
                return check_recorded(env, train_cfg)
            dataset = _read_json(train_cfg).get("dataset") or {}
            if dataset.get("root") and (Path(dataset["root"]) / RECORDED_FILE).is_file():
                path = Path(dataset["root"]) / RECORDED_FILE
                logging.getLogger(__name__).warning(
                    "%s records no task: using the task its dataset %s holds now", train_cfg.parent, path.parent.parent
                )
                return check_recorded(_read_json(path), path)
    return None


def _read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise ConfigError(f"cannot read the recorded env config {path}: {err}") from None
