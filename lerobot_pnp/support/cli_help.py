"""``lerobot-pnp <command> --help``: every option of a command's config dataclass, one entry per field.

Why not draccus's own ``--help``: it builds argparse help from source comments, so a literal ``%`` in a comment
crashes it, a Google-style ``Args:`` line in a class docstring is mistaken for a field (it then prints the
class source), nested configs list ``--policy str`` twice, and the ``Args:`` descriptions (this project's
convention) are not shown per field. This module reads the same dataclasses: a field's description comes from
the class that defines it, its ``Args:`` entry, else the comment draccus would show (above, inline or a
docstring below the field). Nested dataclass fields are listed with their dotted flag
(``--policy.hidden_size``). A field named ``preset`` lists the keys of its module's ``PRESETS`` (else the task
presets, ``presets.PRESETS``), unless its description names them all. Each entry is one description: a long
docstring is cut to its first sentence (the rest stays in the source), reST literal quotes dropped; defaults
print as typed (enums by value, dataclasses as dicts). LeRobot's derived fields (``env.features``,
``policy.input_features`` ...: set from the env or the dataset, never typed) are left out, and the few LeRobot
fields that have no comment of their own get one here (``LEROBOT_FIELD_DOCS``).
"""

from __future__ import annotations

import dataclasses
import enum
import inspect
import re
import shutil
import sys
import textwrap
import typing

# "name: text", "name (type): text" or "a / b / c: text" (one text for several fields)
_ARG_LINE = re.compile(r"^(\s*)(\w+(?: / \w+)*)(?: \([^)]*\))?:\s*(.*)$")
# (LeRobot class, field) -> description, for LeRobot fields without a (right) comment of their own
LEROBOT_FIELD_DOCS: dict[tuple[str, str], str] = {
    ("EnvConfig", "max_parallel_tasks"): "lerobot-eval: tasks of a multi-task env evaluated at once (threads)",
    ("EnvConfig", "disable_env_checker"): "skip gymnasium's env checker in gym.make",
    ("PreTrainedConfig", "repo_id"): "Hub repo (owner/name) the trained policy is pushed to (with push_to_hub)",
    ("PreTrainedConfig", "license"): "license of the policy on the Hub",
}
# (LeRobot class, field) not listed: derived from the env or the dataset when the run starts, never typed
DERIVED_FIELDS = {
    ("EnvConfig", "features"),
    ("EnvConfig", "features_map"),
    ("PreTrainedConfig", "input_features"),
    ("PreTrainedConfig", "output_features"),
}
_LONG = 160  # characters: a description longer than this is cut to its first sentence
_SENTENCE_END = re.compile(r'(?<=[.!?])\s+(?=[A-Z`("])')


def args_section(cls: type) -> dict[str, str]:
    """Field name -> description from the ``Args:`` section of ``cls``'s own docstring."""
    docs: dict[str, str] = {}
    inside, name, indent = False, None, 0
    for line in inspect.cleandoc(cls.__dict__.get("__doc__") or "").splitlines():
        if line.strip() in ("Args:", "Attributes:"):
            inside, name = True, None
            continue
        if not inside:
            continue
        if line and not line[0].isspace():
            inside = False  # the section ended (an unindented line)
            continue
        match = _ARG_LINE.match(line)
        if match and (name is None or len(match.group(1)) <= indent):
            indent, name = len(match.group(1)), match.group(2).split(" / ")
            for one in name:
                docs[one] = match.group(3).strip()
        elif name is not None and line.strip():
            for one in name:
                docs[one] += " " + line.strip()
    return docs


def field_doc(cls: type, name: str) -> str:
    """The description of field ``name``: from the class that (re)defines it nearest to ``cls``, its ``Args:``
    entry, else the comment or attribute docstring draccus would show."""
    for klass in cls.__mro__:
        if name not in inspect.get_annotations(klass):
            continue
        text = LEROBOT_FIELD_DOCS.get((klass.__name__, name)) if klass.__module__.startswith("lerobot.") else None
        text = text or args_section(klass).get(name) or _comment_help(klass, name)
        if text:
            return text
    return ""


def _owner(cls: type, name: str) -> type:
    """The class nearest to ``cls`` that declares field ``name``."""
    return next((k for k in cls.__mro__ if name in inspect.get_annotations(k)), cls)


def is_derived(cls: type, name: str) -> bool:
    """A LeRobot field set from the env or the dataset (``DERIVED_FIELDS``; a subclass may redeclare it), left out
    of the help."""
    return any(k.__module__.startswith("lerobot.") and (k.__name__, name) in DERIVED_FIELDS for k in cls.__mro__)


def annotate_stock_help(cls: type) -> None:
    """LeRobot's own ``--help`` (draccus: ``lerobot-train --env.type=baxter_pnp --help``) of our config ``cls`` as
    ours: the derived fields (``DERIVED_FIELDS``) hidden, the LeRobot fields of ``LEROBOT_FIELD_DOCS`` described.

    Draccus passes a field's ``metadata["custom_args"]`` to argparse's ``add_argument``; ``help=SUPPRESS`` leaves
    the flag out of the usage and the option list (it still parses). The class gets its own copy of an inherited
    field, so LeRobot's classes, and the other envs and policies built on them, keep theirs. Called once per
    config class at registration; calling it again changes nothing.
    """
    import argparse
    import copy
    import types

    own = cls.__dict__["__dataclass_fields__"]
    for field in dataclasses.fields(cls):
        owner = _owner(cls, field.name)
        lerobot_doc = LEROBOT_FIELD_DOCS.get((owner.__name__, field.name)) if _is_lerobot(owner) else None
        text = argparse.SUPPRESS if is_derived(cls, field.name) else lerobot_doc
        custom = dict(field.metadata.get("custom_args", {}))
        if not field.init or text is None or custom.get("help") == text:
            continue
        copied = copy.copy(field)
        copied.metadata = types.MappingProxyType({**field.metadata, "custom_args": {**custom, "help": text}})
        own[field.name] = copied


def _is_lerobot(cls: type) -> bool:
    return cls.__module__.startswith("lerobot.")


def _comment_help(cls: type, name: str) -> str:
    """The help text draccus itself would find in the source (comments or a docstring below the field)."""
    from draccus.wrappers import docstring

    try:
        text = docstring.get_preferred_help_text(docstring.get_attribute_docstring(cls, name))
    except (OSError, TypeError, RuntimeWarning):
        return ""
    return text or ""


def _type_name(tp) -> str:
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    if typing.get_origin(tp) in (typing.Union, getattr(__import__("types"), "UnionType", None)) and len(args) == 1:
        return _type_name(args[0])
    if isinstance(tp, type) and not typing.get_args(tp):
        return tp.__name__
    return re.sub(r"\b(?:\w+\.)+(\w+)", r"\1", str(tp)).replace("NoneType", "None")  # no module paths


def _plain(value):
    """``value`` as typed on the command line: enums as their values (``MEAN_STD``, not
    ``<NormalizationMode.MEAN_STD: 'MEAN_STD'>``), dataclasses as dicts."""
    if isinstance(value, enum.Enum):
        return value.value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):  # as typed: '[{"name": ..., ...}]'
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {_plain(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    return value


def _default_of(field: dataclasses.Field, instance) -> str:
    if instance is not None and hasattr(instance, field.name):
        value = getattr(instance, field.name)
    elif field.default is not dataclasses.MISSING:
        value = field.default
    else:
        return ""
    if dataclasses.is_dataclass(value):
        return ""
    return "none" if value is None else str(value).lower() if isinstance(value, bool) else repr(_plain(value))


def _describe(cls: type, field: dataclasses.Field) -> str:
    text = field_doc(cls, field.name)
    text = " ".join(text.split()).lstrip("-# ")  # a section divider comment above the field is no description
    text = text.replace("``", "")  # reST literals read as plain text in a terminal
    if len(text) > _LONG:
        text = _SENTENCE_END.split(text, maxsplit=1)[0]
    if field.name == "preset":
        presets = getattr(sys.modules.get(_owner(cls, field.name).__module__), "PRESETS", None)
        if presets is None:  # a task preset (e.g. DAgger's demonstrations)
            from lerobot_pnp.presets import PRESETS

            presets = PRESETS
        if isinstance(presets, dict) and not all(re.search(rf"\b{re.escape(p)}\b", text) for p in presets):
            text += f" (one\N{NO-BREAK SPACE}of: {', '.join(sorted(presets))})"
    return text


def field_rows(cls: type, prefix: str = "", instance=None) -> list[tuple[str, str, str]]:
    """``(flag, type, description with default)`` for every field of ``cls``, nested dataclasses flattened."""
    hints = typing.get_type_hints(cls)
    rows: list[tuple[str, str, str]] = []
    for field in dataclasses.fields(cls):
        if not field.init or is_derived(cls, field.name):
            continue
        tp = hints.get(field.name, field.type)
        flag = f"--{prefix}{field.name}"
        if dataclasses.is_dataclass(tp):
            child = getattr(instance, field.name, None) if instance is not None else None
            rows += field_rows(tp, f"{prefix}{field.name}.", child)
            continue
        text = _describe(cls, field)
        default = _default_of(field, instance)
        if default and len(default) <= 40:  # kept on one line when wrapped (a non-breaking space)
            default = default.replace(" ", "\N{NO-BREAK SPACE}")
        rows.append(
            (flag, _type_name(tp), f"{text} [default:\N{NO-BREAK SPACE}{default}]".strip() if default else text)
        )
    return rows


def _default_instance(cls: type):
    """The config with its defaults, for showing them; None if defaults alone do not make a valid config."""
    try:
        return cls()
    except Exception:  # a config that needs a value, or validates against files: show the field defaults
        return None


def command_help(name: str, summary: str, cls: type) -> str:
    """The text of ``lerobot-pnp <name> --help``."""
    width = max(80, min(shutil.get_terminal_size((120, 24)).columns, 140))
    rows = field_rows(cls, instance=_default_instance(cls))
    left = min(max(len(f"  {flag} {tp}") for flag, tp, _ in rows) + 2, 40)
    out = [
        f"usage: lerobot-pnp {name} [--config_path FILE] [--field value ...]",
        "",
        summary,
        "",
        "--config_path FILE: a JSON or YAML file with the same keys (nested as objects); flags override it.",
        "",
        "options:",
    ]
    for flag, tp, text in rows:
        head = f"  {flag} {tp}"
        nbsp = "\N{NO-BREAK SPACE}"
        body = textwrap.wrap(text.replace(" = ", f"{nbsp}={nbsp}"), width - left) or [""]  # "0 = auto" stays whole
        if len(head) + 2 > left:
            out.append(head)
            out += [" " * left + line for line in body if line]
        else:
            out.append(head.ljust(left) + body[0])
            out += [" " * left + line for line in body[1:]]
    return "\n".join(out).replace("\N{NO-BREAK SPACE}", " ")
