"""Cached stages that cannot lie: keys, stage records and the output folder's lock.

A cached stage (a dataset, a training, an evaluation) is reused only when its **key** matches: the sha256 of
the canonical JSON of everything that determines it (config fields, seeds, the keys or content digests of its
inputs, the code versions). The key and its parts are recorded with the stage (``Stage.commit``), after the
stage itself is complete, so a stage folder without a matching record is never trusted by existence alone,
and a mismatch names the parts that changed. Paths never enter a key (a moved folder keeps its keys) and the
records hold only paths relative to their output folder.

What a command may write, replace and delete in its output folder, and its lock: ``lerobot_pnp.outputs``.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.outputs import remove_path as remove  # noqa: F401  (the name its callers import)
from lerobot_pnp.outputs import write_json_atomic
from lerobot_pnp.version import __version__

STAGE_FILE = "stage.json"  # the record of a stage kept in a folder
# Record fields naming an output of the stage, relative to the record's folder (a study training's artefact, a
# DAgger round's checkpoint); a training's record names one. Anything else is not this stage's output.
OUTPUT_FIELDS = ("artifact", "checkpoint")


def canonical(value: Any) -> Any:
    """``value`` as plain JSON values (tuples -> lists, paths -> str, dataclasses -> dicts); rejects NaN."""
    text = json.dumps(value, sort_keys=True, default=_default, allow_nan=True)
    data = json.loads(text)
    if _has_nan(data):
        raise ConfigError(f"a stage key part is not finite: {text[:200]}")
    return data


def _default(value: Any) -> Any:
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "__dataclass_fields__"):
        from dataclasses import asdict

        return asdict(value)
    raise TypeError(f"cannot key a {type(value).__name__}: {value!r}")


def _has_nan(value: Any) -> bool:
    if isinstance(value, float):
        return not math.isfinite(value)
    if isinstance(value, dict):
        return any(_has_nan(v) for v in value.values())
    if isinstance(value, list):
        return any(_has_nan(v) for v in value)
    return False


def key_of(parts: dict) -> str:
    """The stage key: sha256 of the canonical JSON of ``parts``."""
    return hashlib.sha256(json.dumps(canonical(parts), sort_keys=True).encode()).hexdigest()


def code_versions() -> dict[str, str]:
    """The versions of the code a stage's result depends on (this package and LeRobot)."""
    import importlib.metadata as md

    try:
        lerobot = md.version("lerobot")
    except md.PackageNotFoundError:  # pragma: no cover - lerobot is a dependency
        lerobot = "?"
    return {"lerobot_pnp": __version__, "lerobot": lerobot}


def digest_files(root: Path, patterns: tuple[str, ...]) -> str:
    """Content digest of the files under ``root`` matching ``patterns`` (relative names + bytes).

    The key of an input that no stage of this folder produced (a dataset or a checkpoint passed in by
    path): what it holds, not where it is."""
    root = Path(root)
    h = hashlib.sha256()
    files = sorted({p for pattern in patterns for p in root.glob(pattern) if p.is_file()})
    for path in files:
        h.update(str(path.relative_to(root)).encode() + b"\0")
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        h.update(b"\0")
    return h.hexdigest()


DATASET_FILES = ("meta/*.json", "meta/**/*.parquet", "data/**/*.parquet")
CHECKPOINT_FILES = ("*.json", "*.safetensors")


def _same(old: Any, new: Any) -> bool:
    return old == new


def same_env_configs(stored: list[dict] | dict | None, current: list[dict] | dict) -> bool:
    """Whether env configs recorded in a stage's key equal the current ones (one dict or a list of them).

    A task field missing from a stored config was added later and had its paper value ("off") then, an
    observation field its ``OBSERVATION_UNRECORDED`` value, the rule of recorded tasks; other missing keys are
    ignored."""
    from lerobot_pnp.presets import OBSERVATION_UNRECORDED, PAPER_TASK

    if isinstance(current, dict):
        stored, current = [stored] if isinstance(stored, dict) else None, [current]
    if stored is None or len(stored) != len(current):
        return False
    current = json.loads(json.dumps(current))  # tuples -> lists, as stored
    paper = json.loads(json.dumps({**PAPER_TASK, **OBSERVATION_UNRECORDED}))
    return all(
        old.get(k, paper.get(k, v)) == v for old, new in zip(stored, current, strict=True) for k, v in new.items()
    )


class Stage:
    """A cached stage's record: its key and the key's parts, in ``record`` (a JSON file).

    ``compare`` maps a part's name to how an old value is compared with the new one (default: equal), for
    parts with a compatibility rule (e.g. env fields added later that had their paper value then); ``dropped``
    names parts a key once had and no longer has (what they said is determined by the other parts), ignored
    in an old record so that it stays valid; ``added`` maps a part a key did not always have to the value every
    record made before it had (an old record without the part counts as made with that value).
    """

    def __init__(
        self,
        record: Path,
        parts: dict,
        compare: dict[str, Callable[[Any, Any], bool]] | None = None,
        dropped: tuple[str, ...] = (),
        added: dict[str, Any] | None = None,
    ):
        self.record = Path(record)
        self.parts = canonical(parts)
        self.key = key_of(self.parts)
        self.compare = compare or {}
        self.dropped = dropped
        self.added = canonical(added or {})

    def stored(self) -> dict | None:
        """The record on disk, or None when absent or not trusted (``untrusted``)."""
        data, _ = self._load()
        return data

    def _load(self) -> tuple[dict | None, str | None]:
        """(the record, None), or (None, why it is not trusted; None when there is no record)."""
        try:
            data = json.loads(self.record.read_text())
        except FileNotFoundError:
            return None, None
        except (OSError, ValueError) as err:
            return None, f"unreadable ({type(err).__name__})"
        if not isinstance(data, dict) or not isinstance(data.get("parts"), dict):
            return None, "not a stage record"
        named = [f for f in OUTPUT_FIELDS if f in data]
        for field in named:
            if inside(self.record.parent, data[field]) is None:
                return None, f"its {field} {data[field]!r} is not a path inside {self.record.parent}"
        if not named and self.parts.get("stage") == "train":
            return None, "it names no trained artefact"
        return data, None

    def changes(self) -> list[str] | None:
        """None when no record exists; else the names of the parts that differ from the record's."""
        stored = self.stored()
        if stored is None:
            return None
        old = {**self.added, **{k: v for k, v in stored["parts"].items() if k not in self.dropped}}
        names = sorted(set(old) | set(self.parts))
        return [n for n in names if n not in old or n not in self.parts or not self._same(n, old[n])]

    def _same(self, name: str, old: Any) -> bool:
        return self.compare.get(name, _same)(old, self.parts[name])

    def done(self, what: str = "") -> bool:
        """Whether the stage was finished with these parts; logs what changed when it was not."""
        changed = self.changes()
        if changed and what:
            print(f"  {what}: re-run (changed since it was made: {', '.join(changed)})", flush=True)
        elif changed is None and what and (why := self._load()[1]):
            print(f"  {what}: re-run (its record {self.record} is not trusted: {why})", flush=True)
        return changed == []

    def commit(self, **extra: Any) -> None:
        """Record the stage as finished (after its outputs are complete); ``extra`` is stored alongside."""
        extra = json.loads(json.dumps(extra, default=_default))
        write_json_atomic(self.record, {"key": self.key, "parts": self.parts, **extra})

    def invalidate(self) -> None:
        self.record.unlink(missing_ok=True)


def inside(folder: Path, relative: Any) -> Path | None:
    """``folder / relative`` when ``relative`` is a relative path that stays inside ``folder`` (links resolved);
    else None. How a record's path to one of its own outputs is read: never as a path elsewhere on disk."""
    if not isinstance(relative, str) or not relative or Path(relative).is_absolute() or ".." in Path(relative).parts:
        return None
    path = Path(folder) / relative
    return path if path.resolve().is_relative_to(Path(folder).resolve()) else None
