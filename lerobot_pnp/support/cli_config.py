"""How ``lerobot-pnp`` builds a command's config: its dataclass defaults, then ``--config_path``, then the flags.

draccus (the parser) builds a nested dataclass afresh from its type as soon as one of its fields is given
(``--policy.hidden_size 8``), so a default factory that sets more than the type's own defaults (``dagger``'s
``policy`` is the recovering recipe) would lose all of it. So every command is parsed on top of a layer of
defaults: for each nested dataclass field, what its default factory sets beyond its type's defaults (at every
depth), written to a config file with the user's ``--config_path`` merged over it; draccus applies the flags on
top of that file, field by field. A nested field whose type is chosen anew (``--policy.type``, or a ``type`` in
the config file) starts from that type's defaults instead.

Paths: a flag's value starting with ``~`` has the user's home expanded (``--output_dir=~/x``: the shell leaves the
``~`` after ``=`` as it is), for every command alike.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any

from lerobot_pnp.errors import ConfigError, one_line


def expand_home(args: list[str]) -> list[str]:
    """``args`` with ``~`` expanded in each value that starts with it (``--flag=~/x`` or ``--flag ~/x``)."""
    out = []
    for arg in args:
        if arg.startswith("--") and "=" in arg:
            name, value = arg.split("=", 1)
            arg = f"{name}={os.path.expanduser(value)}" if value.startswith("~") else arg
        elif arg.startswith("~"):
            arg = os.path.expanduser(arg)
        out.append(arg)
    return out


def _changed(value: Any) -> dict:
    """What the dataclass instance ``value`` holds beyond its type's defaults, as draccus reads a config file:
    the differing fields (encoded), and inside nested dataclass fields the same, at every depth."""
    import draccus

    try:
        plain = type(value)()
    except Exception:  # a type without defaults for every field: all of it
        return draccus.encode(value)
    out: dict = {}
    for field in dataclasses.fields(value):
        if not field.init:
            continue
        mine, theirs = getattr(value, field.name), getattr(plain, field.name)
        if _is_instance(mine) and type(mine) is type(theirs):
            if nested := _changed(mine):
                out[field.name] = nested
        elif mine != theirs:
            out[field.name] = draccus.encode(mine)
    return out


def _is_instance(value: Any) -> bool:
    return dataclasses.is_dataclass(value) and not isinstance(value, type)


def default_layer(config_cls: type) -> dict:
    """For each nested dataclass field of ``config_cls`` with a default factory: what the factory sets beyond
    the field type's defaults (``_changed``); fields whose factory adds nothing are left out."""
    layer = {}
    for field in dataclasses.fields(config_cls):
        if not field.init or field.default_factory is dataclasses.MISSING:
            continue
        value = field.default_factory()
        if _is_instance(value) and (changed := _changed(value)):
            layer[field.name] = changed
    return layer


def _merge(base: dict, over: dict) -> dict:
    """``over`` on top of ``base``, nested mappings merged key by key."""
    out = dict(base)
    for key, value in over.items():
        below = out.get(key)
        out[key] = _merge(below, value) if isinstance(value, dict) and isinstance(below, dict) else value
    return out


def _default_type(config_cls: type, name: str) -> str | None:
    """The choice name (``type``) of field ``name``'s default factory value, if it has one."""
    field = next((f for f in dataclasses.fields(config_cls) if f.name == name), None)
    if field is None or field.default_factory is dataclasses.MISSING:
        return None
    value = getattr(field.default_factory(), "type", None)
    return None if value is None else str(value)


def _retyped(config_cls: type, args: list[str], data: dict) -> set[str]:
    """The nested fields given another type than their default's, by a ``--FIELD.type=NAME`` flag or a ``type``
    in the config file: they start from that type's own defaults."""
    chosen = {name: value["type"] for name, value in data.items() if isinstance(value, dict) and "type" in value}
    for i, arg in enumerate(args):
        flag, eq, value = arg.partition("=")
        parts = flag.removeprefix("--").split(".")
        if arg.startswith("--") and len(parts) == 2 and parts[1] == "type":
            chosen[parts[0]] = value if eq else (args[i + 1] if i + 1 < len(args) else "")
    return {name for name, kind in chosen.items() if str(kind) != _default_type(config_cls, name)}


def read_config_file(config_cls: type, config_path: str) -> dict:
    """``--config_path``'s mapping, translated where the class reads another program's files (``train``)."""
    from draccus import cfgparsing

    try:
        with open(config_path, encoding="utf-8") as f:
            data = cfgparsing.load_config(f, file=config_path)
    except Exception as err:  # a malformed JSON/YAML file
        raise ConfigError(f"--config_path {config_path!r}: not a readable JSON/YAML config ({one_line(err)})") from err
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(
            f"--config_path {config_path!r}: expected a mapping of config keys, got {type(data).__name__}"
        )
    translate = getattr(config_cls, "translate_config_file", None)
    return translate(data) if translate is not None else data


def layered_config_file(config_cls: type, config_path: str | None, args: list[str], tmp_dir: str) -> str | None:
    """The config file draccus parses ``args`` over: the defaults layer (``default_layer``) with
    ``config_path``'s mapping merged on top; None when both are empty. A nested field given another type
    (``_retyped``) has no defaults layer."""
    data = read_config_file(config_cls, config_path) if config_path else {}
    layer = default_layer(config_cls)
    for name in _retyped(config_cls, args, data):
        layer.pop(name, None)
    merged = _merge(layer, data)
    if config_path is None and not merged:
        return None
    out = Path(tmp_dir) / "config.json"
    out.write_text(json.dumps(merged, default=str))
    return str(out)
