"""The documentation's Python snippets run as written.

Every ```python block of the pages in PAGES is executed in a Python process of its own, in an empty folder, with
this checkout first on the import path and the project's environment (one thread, headless EGL rendering, the Hub
offline): each block stands alone, imports included. The process is forked from an interpreter that has imported
torch and LeRobot and nothing of this project (tests/zygote.py); the block still imports every name it uses.
Every page with a ```python block must be in PAGES, so a new snippet cannot go unexecuted. The quick check (every
block compiles and its ``from X import Y`` names exist) runs in the default loop; running the blocks is marked
``slow`` (``make test`` and CI run it).
"""

from __future__ import annotations

import ast
import importlib
import re
import sys
from pathlib import Path

import pytest
import zygote

ROOT = Path(__file__).resolve().parents[1]
PAGES = ("docs/guides/python.md", "docs/getting-started.md")


def python_blocks(text: str) -> list[tuple[int, str]]:
    """(first line number, code) of every ```python block of a markdown text."""
    out = []
    for m in re.finditer(r"^```python\n(.*?)^```\s*$", text, re.M | re.S):
        out.append((text.count("\n", 0, m.start()) + 2, m.group(1)))
    return out


SNIPPETS = [(f"{page}:{line}", code) for page in PAGES for line, code in python_blocks((ROOT / page).read_text())]


def test_every_page_with_python_snippets_is_executed():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    with_snippets = {str(p.relative_to(ROOT)) for p in pages if python_blocks(p.read_text())}
    assert with_snippets <= set(PAGES), f"add to PAGES: {sorted(with_snippets - set(PAGES))}"
    assert len(SNIPPETS) >= 5


@pytest.mark.parametrize("where, code", SNIPPETS, ids=[w for w, _ in SNIPPETS])
def test_a_snippet_compiles_and_imports_names_that_exist(where, code):
    tree = ast.parse(code, filename=where)
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("lerobot_pnp"):
            module = importlib.import_module(node.module)
            missing = [a.name for a in node.names if not hasattr(module, a.name)]
            assert not missing, f"{where}: {node.module} has no {missing}"


@pytest.mark.slow
@pytest.mark.parametrize("where, code", SNIPPETS, ids=[w for w, _ in SNIPPETS])
def test_a_snippet_runs_as_written(where, code, tmp_path):
    proc = zygote.run([sys.executable, "-c", code], tmp_path, timeout=300)
    assert proc.returncode == 0, f"{where} failed:\n{code}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"


def test_a_failing_snippet_fails(tmp_path):
    """The runner reports a snippet that raises (a renamed field, a missing import)."""
    code = 'import gymnasium as gym\nimport lerobot_pnp\ngym.make("lerobot_pnp/BaxterPnP-v0", no_such_field=1)\n'
    proc = zygote.run([sys.executable, "-c", code], tmp_path)
    assert proc.returncode != 0 and "no_such_field" in proc.stderr
