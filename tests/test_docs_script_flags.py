"""Every benchmark and script command the README and the documentation show names a file of this repository and only
flags that file's parser declares, spelled as it declares them (argparse would also take an abbreviation; a page
does not). ``tests/test_docs_commands.py`` checks the ``lerobot-*`` commands the same way."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

from test_docs_commands import shell_blocks

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = re.compile(r"^(?:\S*/)?python3?$")


def script_commands() -> list[tuple[str, str, list[str]]]:
    """(page:line, script path, its arguments) of every ``python benchmarks/X.py`` / ``python scripts/X.py``."""
    out = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        rel = str(page.relative_to(ROOT))
        for first_line, body in shell_blocks(page.read_text()):
            joined = re.sub(r"\\\n\s*", " ", body)
            for i, line in enumerate(joined.splitlines()):
                try:
                    tokens = shlex.split(line, comments=True)
                except ValueError:
                    continue
                for j, token in enumerate(tokens[:-1]):
                    if SCRIPT.match(token) and re.match(r"(benchmarks|scripts)/\w+\.py$", tokens[j + 1]):
                        args = [t for t in tokens[j + 2 :] if t not in {";", "&&", "|"}]
                        stop = next((k for k, t in enumerate(args) if SCRIPT.match(t) or t.startswith("lerobot")), None)
                        out.append((f"{rel}:{first_line + i}", tokens[j + 1], args[:stop]))
    return out


def declared(script: str) -> set[str]:
    """The long options a script's argparse parser declares (every ``"--name"`` literal of the file)."""
    return set(re.findall(r"[\"'](--[\w-]+)[\"']", (ROOT / script).read_text()))


def test_every_documented_script_command_uses_flags_its_parser_declares():
    commands = script_commands()
    assert len(commands) >= 15, commands  # the pages' benchmark and script commands were found
    wrong = []
    for where, script, args in commands:
        if not (ROOT / script).is_file():
            wrong.append(f"{where}: {script} does not exist")
            continue
        flags = {a.split("=")[0] for a in args if a.startswith("--")}
        if unknown := sorted(flags - declared(script)):
            wrong.append(f"{where}: {script} does not declare {unknown}")
    assert not wrong, "\n".join(wrong)


def test_an_undeclared_or_abbreviated_flag_is_caught():
    assert "--num_episodes" in declared("benchmarks/pixel_planner.py")
    assert "--episode" not in declared("benchmarks/pixel_planner.py")
