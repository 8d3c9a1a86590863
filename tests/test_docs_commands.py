"""Every command the README and the documentation show exists as written: parsed, never run.

Each fenced shell block (```bash, ```sh, ```shell, ```console) of README.md and docs/**/*.md is read as a shell
would read it (``\\`` continuations joined, ``;``, ``&&`` and ``|`` separating commands), and every
``lerobot-pnp``, ``lerobot-train`` and ``lerobot-eval`` command in it is checked:

- ``lerobot-pnp <sub-command>`` names one of ``lerobot_pnp.cli.COMMANDS``;
- every ``--flag`` is a field of the config the command parses into, nested with dots as draccus nests them
  (``--policy.hidden_size``): for ``lerobot-pnp`` the sub-command's config class (``train``: the one its policy
  type picks), for ``lerobot-train`` / ``lerobot-eval`` LeRobot's ``TrainPipelineConfig`` / ``EvalPipelineConfig``
  with ``--env.*`` of the env type and ``--policy.*`` of the policy type the command line or its config file names
  (our env config ``baxter_pnp`` when none is named; with no policy type, e.g. ``--policy.path``, a field of any of
  the policies the documentation uses);
- every ``--config_path FILE``, and any other value naming a shipped config (``configs/*.json``), is a file of
  this repository.

What is not checked, and why: commands in ```text blocks (they are ``--help`` output, generated from the code by
``scripts/docs_tables.py`` and checked by tests/test_docs_tables.py); commands in inline code (prose, often a
placeholder such as ``lerobot-pnp <command>``); flag values (they name folders a run makes, or placeholders).
"""

from __future__ import annotations

import dataclasses
import json
import re
import shlex
import types
import typing
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PLACEHOLDER = "PLACEHOLDER"
SHELL_BLOCKS = {"bash", "sh", "shell", "console"}
NAMES = ("lerobot-pnp", "lerobot-train", "lerobot-eval")
SEPARATORS = {";", "&&", "||", "|", "&"}
PREFIXES = {"do", "then", "else", "time", "nohup", "exec", "$"}  # words a command may follow in a line
# the policy types a `--policy.*` flag is looked up in when the command names none (`--policy.path CHECKPOINT`)
SHOWN_POLICIES = ("pnp_lstm", "pnp_pixels", "pnp_lookup_table", "act", "diffusion")
# arguments LeRobot's parser reads itself, beside the config's fields
STOCK_SPECIAL = {"config_path", "help", "policy.path", "env.type", "policy.type"}


@dataclass
class Command:
    where: str  # file:line
    argv: list[str]

    def __str__(self) -> str:
        return f"{self.where}: {shlex.join(self.argv)[:160]}"


# ---------------------------------------------------------------------------------------------- extraction
def shell_blocks(text: str) -> list[tuple[int, str]]:
    """(first line number, body) of every shell block of a markdown text: fenced ones of a shell language, and
    indented ones (four spaces after a blank line, outside a fence), which the result pages use for commands."""
    out, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        opening = re.match(r"\s*```(\w*)\s*$", lines[i])
        if opening:
            end = next((j for j in range(i + 1, len(lines)) if re.match(r"\s*```\s*$", lines[j])), len(lines))
            if opening.group(1) in SHELL_BLOCKS:
                out.append((i + 2, "\n".join(lines[i + 1 : end])))
            i = end + 1
        elif lines[i].startswith("    ") and lines[i].strip() and (i == 0 or not lines[i - 1].strip()):
            end = i
            while end < len(lines) and (lines[end].startswith("    ") or not lines[end].strip()):
                end += 1
            out.append((i + 1, "\n".join(line[4:] for line in lines[i:end])))
            i = end
        else:
            i += 1
    return out


def commands_in(block: str, where: str, first_line: int) -> list[Command]:
    """The lerobot commands of one shell block, each split as a shell would split it."""
    out = []
    lines = block.split("\n")
    i = 0
    while i < len(lines):
        start, line = i, lines[i]
        while line.rstrip().endswith("\\") and i + 1 < len(lines):
            i += 1
            line = line.rstrip()[:-1] + " " + lines[i]
        i += 1
        lexer = shlex.shlex(line, posix=True, punctuation_chars=";&|")
        lexer.whitespace_split, lexer.commenters = True, "#"
        try:
            tokens = list(lexer)
        except ValueError as err:  # an unclosed quote: prose in an indented block, or a broken command
            if any(re.search(rf"(^|\s){n}\s", line) for n in NAMES):
                raise AssertionError(f"{where}:{first_line + start}: cannot split {line!r}: {err}") from None
            continue
        segment: list[str] = []
        for token in [*tokens, ";"]:
            if token not in SEPARATORS:
                segment.append(token)
                continue
            while segment and (segment[0] in PREFIXES or re.match(r"\w+=", segment[0])):
                segment = segment[1:]  # `for ...; do CMD`, `HF_HUB_OFFLINE=0 CMD`, `$ CMD`
            if segment and segment[0] in NAMES:
                out.append(Command(f"{where}:{first_line + start}", segment))
            segment = []
    return out


def inline_commands(text: str) -> list[tuple[int, str]]:
    """(line number, code) of every inline code span outside the blocks that starts with a command's name."""
    out = []
    for i, line in enumerate(text.splitlines(), 1):
        out += [(i, m.group(1)) for m in re.finditer(rf"`((?:{'|'.join(NAMES)}) [^`]+)`", line)]
    return out


def _without_blocks(text: str) -> str:
    """The text with every fenced block's lines blanked (line numbers kept)."""
    lines, inside = text.splitlines(), False
    for i, line in enumerate(lines):
        fence = re.match(r"\s*```", line) is not None
        if inside or fence:
            lines[i] = ""
        inside = inside != fence
    return "\n".join(lines)


def documented_commands() -> list[Command]:
    """Every command of the README and the documentation, in blocks and in inline code; a placeholder
    (``<checkpoint>``) reads as one word, and a command whose sub-command is one (``lerobot-pnp <command>``) is
    left out."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    out = []
    for page in pages:
        rel, text = str(page.relative_to(ROOT)), page.read_text()
        for first_line, body in [*shell_blocks(text), *inline_commands(_without_blocks(text))]:
            out += commands_in(re.sub(r"<[^<>\n]*>", PLACEHOLDER, body), rel, first_line)
    return [c for c in out if c.argv[0] != "lerobot-pnp" or c.argv[1:2] != [PLACEHOLDER]]


def flags_of(argv: list[str]) -> dict[str, str | None]:
    """``--name`` -> its value (None for a bare flag), for every flag of a command line."""
    out: dict[str, str | None] = {}
    for i, arg in enumerate(argv):
        if arg.startswith("--"):
            name, eq, value = arg[2:].partition("=")
            if not eq:
                nxt = argv[i + 1] if i + 1 < len(argv) else None
                value = nxt if nxt is not None and not nxt.startswith("--") else None
            out[name] = value
    return out


# ---------------------------------------------------------------------------------------------- resolution
def _members(tp) -> list:
    """The types a field may hold: the members of a union other than None, else the type itself."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        return [a for a in typing.get_args(tp) if a is not type(None)]
    return [tp]


def _hints(cls: type) -> dict:
    try:
        return typing.get_type_hints(cls)
    except Exception:  # a forward reference the module cannot resolve: the declared types as written
        return {f.name: f.type for f in dataclasses.fields(cls)}


def has_field(cls: type, path: str, choose, prefix: str = "") -> bool:
    """Whether ``--<path>`` names a field of dataclass ``cls``, nested with dots; ``choose(prefix, type)`` gives
    the classes a field of a registry type (a policy, an env) is looked up in."""
    head, _, rest = path.partition(".")
    if not dataclasses.is_dataclass(cls) or head not in {f.name for f in dataclasses.fields(cls)}:
        return False
    if not rest:
        return True
    here = f"{prefix}{head}"
    for tp in _members(_hints(cls)[head]):
        if tp is dict or typing.get_origin(tp) is dict:
            return True  # a dict field takes any key (--rename_map.X)
        nested = isinstance(tp, type) and dataclasses.is_dataclass(tp)
        if nested and any(has_field(c, rest, choose, here + ".") for c in choose(here, tp)):
            return True
    return False


def _is_registry_base(tp: type) -> bool:
    """A draccus choice registry's base class (``PreTrainedConfig``, ``EnvConfig``), not one of its choices."""
    from draccus.choice_types import ChoiceRegistry

    return issubclass(tp, ChoiceRegistry) and tp not in tp.get_known_choices().values()


def _file_value(config_path: str | None, dotted: str):
    """A dotted key of a JSON config file (``policy.type``), None when absent."""
    if not config_path or not (ROOT / config_path).is_file() or not config_path.endswith(".json"):
        return None
    value = json.loads((ROOT / config_path).read_text())
    for key in dotted.split("."):
        value = value.get(key) if isinstance(value, dict) else None
    return value


def stock_chooser(flags: dict[str, str | None]):
    """How ``lerobot-train`` / ``lerobot-eval`` pick a registry field's class: the type the command line or its
    config file names; else our env, and for the policy any of the documented policy types."""
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    def choose(here: str, tp: type) -> list[type]:
        if not _is_registry_base(tp):
            return [tp]
        name = flags.get(f"{here}.type") or _file_value(flags.get("config_path"), f"{here}.type")
        known = tp.get_known_choices()
        if name:
            return [known[name]] if name in known else []
        if here == "env":
            return [BaxterPnPEnvConfig]
        if here == "policy":
            return [known[n] for n in SHOWN_POLICIES]
        return [tp]

    return choose


def _rooted(args: list[str]) -> list[str]:
    """``args`` with the value of ``--config_path`` made absolute: the documentation runs from the repository's
    root."""
    out = list(args)
    for i, arg in enumerate(out):
        if arg.startswith("--config_path="):
            out[i] = f"--config_path={ROOT / arg.split('=', 1)[1]}"
        elif arg == "--config_path" and i + 1 < len(out):
            out[i + 1] = str(ROOT / out[i + 1])
    return out


def unknown_flags(command: Command) -> list[str]:
    """What is wrong with one documented command (run from the repository's root): an unknown sub-command, an
    unknown flag, a missing config file; empty when nothing is."""
    from lerobot_pnp.cli import COMMANDS, command_config
    from lerobot_pnp.errors import PnPError

    name, args = command.argv[0], command.argv[1:]
    flags = flags_of(args)
    config_path = flags.get("config_path")
    if "config_path" in flags and not (config_path and (ROOT / config_path).is_file()):
        return [f"--config_path {config_path}: no such file in the repository"]
    shipped = [a.split("=", 1)[-1] for a in args if re.fullmatch(r"(--[\w.]+=)?configs/\S+\.(json|ya?ml)", a)]
    missing = [f"{path}: no such file in the repository" for path in shipped if not (ROOT / path).is_file()]
    if missing:  # another flag naming a shipped config (report --alongside configs/...)
        return missing
    if name == "lerobot-pnp":
        if not args or args[0] not in COMMANDS:
            return [f"no sub-command {args[0] if args else ''!r}; valid: {sorted(COMMANDS)}"]
        try:  # the class the command parses into (train: by its policy type), as lerobot-pnp picks it
            cls, _, rest = command_config(args[0], _rooted(args[1:]))
        except PnPError as err:
            return [str(err)]
        flags = {k.replace("-", "_"): v for k, v in flags_of(rest).items()}
        special, choose = {"help"}, lambda here, tp: [tp]
    else:
        from lerobot.configs.eval import EvalPipelineConfig
        from lerobot.configs.train import TrainPipelineConfig

        cls = TrainPipelineConfig if name == "lerobot-train" else EvalPipelineConfig
        special, choose = STOCK_SPECIAL, stock_chooser(flags)
    return [f"--{f}" for f in flags if f not in special and not has_field(cls, f, choose)]


# ---------------------------------------------------------------------------------------------- tests
@pytest.fixture(scope="module")
def at_root():
    """Every config registered: ours, and LeRobot's policies (ACT, Diffusion ...)."""
    from lerobot_pnp.integration.registration import register_all

    register_all()
    import lerobot.policies  # noqa: F401


def test_the_documentation_shows_commands_of_each_kind():
    names = {c.argv[0] for c in documented_commands()}
    assert names == set(NAMES)
    assert len(documented_commands()) > 50


def test_every_documented_command_exists_as_written(at_root):
    wrong = [f"{c}\n    {'; '.join(p)}" for c in documented_commands() if (p := unknown_flags(c))]
    assert not wrong, "documented commands that do not parse:\n" + "\n".join(wrong)


@pytest.mark.parametrize(
    "line, wrong",
    [
        ("lerobot-pnp train --dataset_root d --epochz 3", ["--epochz"]),
        ("lerobot-pnp train --policy.type pnp_pixels --policy.num_keypoints 8 --policy.chunk_size 4", ["--policy.chunk_size"]),
        ("lerobot-pnp generate --env.preset full --env.made_up 1 --num-episodes 2", ["--env.made_up"]),
        ("lerobot-eval --policy.path p --env.type baxter_pnp --env.made_up 1 --eval.n_episodez 3", ["--env.made_up", "--eval.n_episodez"]),
        ("lerobot-train --policy.type act --policy.chunk_size 8 --policy.hidden_size 8", ["--policy.hidden_size"]),
        ("lerobot-train --config_path configs/train_act_images.json --policy.hidden_size 8", ["--policy.hidden_size"]),
        ("lerobot-train --config_path configs/no_such.json", ["--config_path configs/no_such.json: no such file in the repository"]),
        ("lerobot-pnp report --config_path configs/report_full.json --alongside configs/no_such.json", ["configs/no_such.json: no such file in the repository"]),
        ("lerobot-pnp viz --policy.path p --device cuda --n_episodes 2", []),
        ("lerobot-train --policy.type pnp_lstm --policy.hidden_size 8 --dataset.root d --rename_map.a b", []),
    ],
)  # fmt: skip
def test_a_made_up_flag_or_file_is_caught(at_root, line, wrong):
    assert unknown_flags(Command("page.md:1", shlex.split(line))) == wrong


def test_a_made_up_sub_command_is_caught(at_root):
    (problem,) = unknown_flags(Command("page.md:1", ["lerobot-pnp", "trian", "--epochs", "3"]))
    assert problem.startswith("no sub-command 'trian'; valid: ['compare', 'dagger', ")


def test_commands_are_read_as_a_shell_reads_them(at_root):
    page = (
        "Text with `lerobot-pnp demo --quick` inline.\n\n```bash\n"
        "HF_HUB_OFFLINE=0 lerobot-pnp train --dataset_root d \\\n    --epochs 3   # a comment --nope\n"
        "for s in 1 2; do lerobot-eval --policy.path <checkpoint> --eval.n_episodez 2; done\n"
        "make demo && lerobot-pnp <command> --help | head\n```\n\n"
        "    lerobot-train --policy.type act --policy.made_up 1\n"
    )
    blocks = [*shell_blocks(page), *inline_commands(_without_blocks(page))]
    found = [c for line, body in blocks for c in commands_in(body, "page.md", line)]
    assert [c.argv[:2] for c in found] == [
        ["lerobot-pnp", "train"], ["lerobot-eval", "--policy.path"], ["lerobot-pnp", "<command>"],
        ["lerobot-train", "--policy.type"], ["lerobot-pnp", "demo"],
    ]  # fmt: skip
    assert [c.where for c in found] == ["page.md:4", "page.md:6", "page.md:7", "page.md:10", "page.md:1"]
    assert [unknown_flags(c) for c in (found[0], found[1], found[3], found[4])] == [
        [],
        ["--eval.n_episodez"],
        ["--policy.made_up"],
        [],
    ]
