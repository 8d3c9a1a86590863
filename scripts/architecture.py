"""The module map of docs/ARCHITECTURE.md, drawn from the code: the layers of ``pyproject.toml`` and every package
and module of ``lerobot_pnp`` with the opening of its docstring.

    python scripts/architecture.py          # print the map
    python scripts/docs_tables.py           # write it into docs/ARCHITECTURE.md (its ``architecture-*`` blocks)
    python scripts/docs_tables.py --check   # exit 1 when the page differs from the code (tests/test_architecture.py)

The map reads the source files (``ast``) and the import contracts (``tomllib``) and imports nothing of the
package, so it is the same wherever it runs. A module without a docstring, or a top-level module or package that
no layer names, is an error: every entry of the map says what it is, and the map covers the whole package.
"""

from __future__ import annotations

import ast
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "lerobot_pnp"
SUMMARY_CHARS = 50  # a summary takes the docstring's sentences until it is at least this long
SENTENCE_END = re.compile(r"(?<=[.!?])\s+(?=[A-Z(`])")


class MapError(SystemExit):
    """What keeps the map from covering the package: one line naming the file or the layer."""


def contracts(root: Path = ROOT) -> dict[str, dict]:
    """``pyproject.toml``'s import-linter contracts by type (``layers``, ``acyclic_siblings``)."""
    config = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["importlinter"]
    return {c["type"]: c for c in config["contracts"]}


def summary(path: Path, root: Path = ROOT) -> str:
    """The opening of a module's docstring as markdown: its first sentences, until the text says what the module
    is (at least ``SUMMARY_CHARS`` characters, never past the first paragraph)."""
    doc = ast.get_docstring(ast.parse(path.read_text(), str(path)))
    if not doc or not doc.strip():
        raise MapError(f"{path.relative_to(root)} has no docstring: its opening is the module's entry in the map")
    paragraph = " ".join(doc.strip().split("\n\n")[0].split())
    text = ""
    for sentence in SENTENCE_END.split(paragraph):
        text = f"{text} {sentence}".strip()
        if len(text) >= SUMMARY_CHARS:
            break
    return text.replace("``", "`").replace("|", "\\|")


def _members(layer: str) -> list[str]:
    return [m.strip() for m in layer.split("|")]


def _path(package: Path, name: str) -> Path:
    """The file that documents a member of a layer: its ``__init__.py`` for a package, else the module."""
    return package / name / "__init__.py" if (package / name).is_dir() else package / f"{name}.py"


def _top_level(package: Path) -> set[str]:
    names = {p.stem for p in package.glob("*.py") if p.name != "__init__.py"}
    return names | {p.name for p in package.iterdir() if (p / "__init__.py").is_file()}


def layer_table(root: Path = ROOT) -> str:
    """The layers, top to bottom, each member with what it is; the imports let through and the cycle contract."""
    package, c = root / PACKAGE, contracts(root)
    layers = c["layers"]["layers"]
    named = [m for layer in layers for m in _members(layer)]
    if missing := sorted(_top_level(package) - set(named)):
        raise MapError(f"pyproject.toml: no layer names {missing}; add each to the layer it belongs in")
    lines = ["| layer | package or module | what it is |", "|---|---|---|"]
    for i, layer in enumerate(layers, 1):
        for j, name in enumerate(_members(layer)):
            shown = f"`{name}/`" if (package / name).is_dir() else f"`{name}.py`"
            lines.append(f"| {i if j == 0 else ''} | {shown} | {summary(_path(package, name), root)} |")
    let_through = ", ".join(f"`{i}`" for i in c["layers"].get("ignore_imports", [])) or "none"
    return "\n".join(
        [
            f"The `layers` contract of `pyproject.toml`, top (1) to bottom ({len(layers)}): a module imports only "
            "from the layers below its own, imports inside functions included; members of one layer import "
            f"nothing of each other. Imports let through: {let_through}. The `{c['acyclic_siblings']['name']}` "
            "contract: no import goes round among the modules of any package, at any depth.",
            "",
            *lines,
        ]
    )


def module_tables(root: Path = ROOT) -> str:
    """Every package of the map, in layer order, with each of its modules and what it is."""
    package = root / PACKAGE
    out = []
    for layer in contracts(root)["layers"]["layers"]:
        for name in _members(layer):
            folder = package / name
            if not folder.is_dir():
                continue
            out += ["", f"### `{name}/`", "", summary(folder / "__init__.py", root), ""]
            out += ["| module | what it is |", "|---|---|"]
            for path in sorted(p for p in folder.rglob("*.py") if p.name != "__init__.py"):
                out.append(f"| `{path.relative_to(folder).as_posix()}` | {summary(path, root)} |")
    return "\n".join(out).lstrip("\n")


# docs/ARCHITECTURE.md's generated blocks (``scripts/docs_tables.py`` renders them; ``base`` is unused)
BLOCKS = {"architecture-layers": lambda base: layer_table(), "architecture-modules": lambda base: module_tables()}

if __name__ == "__main__":
    try:
        print(layer_table() + "\n\n" + module_tables())
    except MapError as e:
        sys.exit(str(e))
