"""One ``eval_info.json`` (stock ``lerobot-eval``'s output, or ``lerobot-pnp expert``'s) read and checked.

``per_task`` lists a suite (``task_group``) and task id per entry, with ``metrics.successes`` per episode in seed
order. Stock ``lerobot-eval`` records no seed, neither in the file nor elsewhere in its output folder: episode
``i`` of every task is seed ``--seed + i``. ``lerobot-pnp expert`` also writes ``metrics.seeds``, each episode's
seed; they are kept (``EvalInfo.seeds``) so that runs recorded on other seeds are not paired.

Only the successes and seeds are kept while the file is parsed: every other per-episode list (rewards, failure
causes, video paths) is dropped as soon as its task's ``metrics`` object is complete, so memory holds the file's
text and what is kept, not every number in it. A file larger than ``MAX_INPUT_BYTES`` is refused before it is
read (100,000 episodes on each of the held-out protocol's 18 suites: about 85 MB from stock ``lerobot-eval``,
145 MB from ``lerobot-pnp expert``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_pnp.errors import ConfigError, one_line

MAX_INPUT_BYTES = 512 * 2**20  # the largest eval_info.json read
KEPT_METRICS = ("successes", "seeds")  # of a task's metrics, what is kept while parsing


@dataclass(frozen=True)
class EvalInfo:
    """suite -> task id -> per-episode successes, and the seeds of the tasks that record them."""

    file: Path
    suites: dict[str, dict[int, list[bool]]]
    seeds: dict[str, dict[int, list[int]]]  # only the tasks whose metrics record ``seeds``


def eval_info_file(path: str | Path) -> Path:
    """The ``eval_info.json`` of ``path`` (a folder holding it, or the file), refused in one line when absent."""
    file = Path(path) / "eval_info.json" if Path(path).is_dir() else Path(path)
    if not file.is_file():
        raise ConfigError(f"compare: no eval_info.json at {str(path)!r}")
    return file


def _load(file: Path) -> dict:
    size = file.stat().st_size
    if size > MAX_INPUT_BYTES:
        raise ConfigError(
            f"compare: {str(file)!r} holds {size:,} bytes, over the {MAX_INPUT_BYTES:,} "
            f"({MAX_INPUT_BYTES / 2**20:g} MiB) an eval_info.json may hold here; evaluate fewer episodes per run, or "
            "split the suites over several runs"
        )
    try:
        return json.loads(file.read_text(encoding="utf-8"), object_pairs_hook=_lean)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:
        raise ConfigError(f"compare: {str(file)!r} is not JSON ({one_line(err)[:200]})") from None
    except MemoryError:
        raise ConfigError(f"compare: {str(file)!r} ({size / 2**20:.0f} MiB) does not fit in memory") from None


def _lean(pairs: list[tuple[str, object]]) -> dict:
    """A parsed JSON object; a task's ``metrics`` (the object holding ``successes``) keeps only ``KEPT_METRICS``,
    so that the other per-episode lists are freed while the rest of the file is parsed."""
    obj = dict(pairs)
    if isinstance(obj.get("successes"), list):
        return {k: obj[k] for k in KEPT_METRICS if k in obj}
    return obj


def _array(values: list) -> np.ndarray | None:
    try:
        return np.asarray(values)
    except (ValueError, TypeError, OverflowError):  # nested lists of other lengths, and the like
        return None


def _outcomes(values) -> list[bool] | None:
    """A list of booleans (or 0 / 1) as a list of bools; None when it is anything else."""
    if not isinstance(values, list) or not values:
        return None
    arr = _array(values)
    if arr is None or arr.ndim != 1 or arr.dtype.kind not in "biuf":
        return None
    if arr.dtype.kind != "b" and not np.isin(arr, (0, 1)).all():
        return None
    return arr.astype(bool).tolist()


def _seeds(values, n: int) -> list[int] | None:
    """One integer per episode, or None when it is anything else."""
    if not isinstance(values, list) or len(values) != n:
        return None
    arr = _array(values)
    if arr is None or arr.ndim != 1 or arr.dtype.kind not in "iu":
        return None
    return arr.tolist()


def read_eval_info(path: str | Path) -> EvalInfo:
    """The suites, tasks, successes and recorded seeds of one ``eval_info.json`` (a folder holding it, or the
    file); anything malformed is refused in one line naming the file."""
    file = eval_info_file(path)
    data = _load(file)
    foreign = f"compare: {str(file)!r} is not a lerobot-eval eval_info.json"
    if not isinstance(data, dict) or not isinstance(data.get("per_task"), list) or not data["per_task"]:
        raise ConfigError(f"{foreign} (no per_task list)")
    suites: dict[str, dict[int, list[bool]]] = {}
    seeds: dict[str, dict[int, list[int]]] = {}
    for entry in data["per_task"]:
        try:
            group, task_id, metrics = entry["task_group"], entry["task_id"], entry["metrics"]
            raw = metrics["successes"]
        except (TypeError, KeyError):
            raise ConfigError(f"{foreign} (a per_task entry without task_group, task_id, metrics.successes)") from None
        if not isinstance(group, str) or not isinstance(task_id, int) or isinstance(task_id, bool):
            raise ConfigError(f"{foreign} (per_task entry {group!r}, {task_id!r}: task_group text, task_id integer)")
        successes = _outcomes(raw)
        if successes is None or task_id in suites.get(group, {}):
            raise ConfigError(f"{foreign} (suite {group!r} task {task_id}: no episodes, non-boolean or repeated)")
        suites.setdefault(group, {})[task_id] = successes
        if "seeds" in metrics:
            recorded = _seeds(metrics["seeds"], len(successes))
            if recorded is None:
                raise ConfigError(f"{foreign} (suite {group!r} task {task_id}: seeds is not one integer per episode)")
            seeds.setdefault(group, {})[task_id] = recorded
    _check_per_group(data.get("per_group"), suites, foreign)
    return EvalInfo(file, suites, seeds)


def _check_per_group(per_group, suites: dict[str, dict[int, list[bool]]], foreign: str) -> None:
    """Stock eval writes ``per_group`` beside ``per_task``: where present, it must count the same episodes."""
    if per_group is None:
        return
    if not isinstance(per_group, dict):
        raise ConfigError(f"{foreign} (per_group is a {type(per_group).__name__}, not a mapping of suites)")
    for group, stats in per_group.items():
        n = sum(len(v) for v in suites.get(group, {}).values())
        if not isinstance(stats, dict) or stats.get("n_episodes") != n:
            raise ConfigError(f"{foreign} (per_group[{group!r}] does not count the {n} episodes of per_task)")
