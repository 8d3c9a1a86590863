"""docs/ARCHITECTURE.md's module map is the code's: its layers are ``pyproject.toml``'s import contracts and its
entries are the package's modules with the opening of their docstrings (``scripts/architecture.py``, rendered into
the page by ``scripts/docs_tables.py``). The page fails this test once it differs from what the code gives."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
from clis import load_script

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "ARCHITECTURE.md"


@pytest.fixture(scope="module")
def arch():
    return load_script("scripts/architecture.py")


def _block(text: str, name: str) -> str:
    return re.search(rf"<!-- begin generated: {name} -->\n(.*?)\n<!-- end generated: {name} -->", text, re.S).group(1)


def _copy(tmp_path: Path) -> Path:
    """The package's sources and its contracts under ``tmp_path``."""
    shutil.copytree(ROOT / "lerobot_pnp", tmp_path / "lerobot_pnp", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    return tmp_path


def test_the_committed_page_is_the_map_the_code_gives(arch):
    text = PAGE.read_text()
    assert _block(text, "architecture-layers") == arch.layer_table(), "run `python scripts/docs_tables.py`"
    assert _block(text, "architecture-modules") == arch.module_tables(), "run `python scripts/docs_tables.py`"


def test_every_module_and_layer_is_on_the_page(arch):
    text = PAGE.read_text()
    layers = arch.contracts()["layers"]["layers"]
    for i, layer in enumerate(layers, 1):
        first = layer.split("|")[0].strip()
        assert re.search(rf"^\| {i} \| `{first}(/|\.py)` \|", text, re.M), layer
    for path in (ROOT / "lerobot_pnp").rglob("*.py"):
        if path.parent.name != "lerobot_pnp" and path.name != "__init__.py":
            assert f"| `{path.name}` |" in text, path


def test_a_new_module_changes_the_map(arch, tmp_path):
    """A module added to a copy of the package is an entry of its package's table, its docstring's opening."""
    root = _copy(tmp_path)
    (root / "lerobot_pnp" / "sim" / "wind.py").write_text('"""Gusts of wind that push the cube. More text."""\n')
    changed = arch.module_tables(root)
    assert changed != arch.module_tables()
    assert "| `wind.py` | Gusts of wind that push the cube. More text. |" in changed
    assert changed.index("`wind.py`") > changed.index("### `sim/`") > changed.index("### `dataset/`")


def test_a_changed_layer_order_changes_the_map(arch, tmp_path):
    root = _copy(tmp_path)
    toml = root / "pyproject.toml"
    toml.write_text(toml.read_text().replace('    "viz",\n    "dagger",\n', '    "dagger",\n    "viz",\n'))
    table = arch.layer_table(root)
    assert "| 3 | `dagger/` |" in table and "| 4 | `viz/` |" in table
    assert arch.module_tables(root).index("### `dagger/`") < arch.module_tables(root).index("### `viz/`")


def test_a_module_without_a_docstring_is_refused(arch, tmp_path):
    root = _copy(tmp_path)
    (root / "lerobot_pnp" / "sim" / "bare.py").write_text("X = 1\n")
    with pytest.raises(SystemExit, match=r"lerobot_pnp/sim/bare.py has no docstring"):
        arch.module_tables(root)


def test_a_top_level_module_in_no_layer_is_refused(arch, tmp_path):
    root = _copy(tmp_path)
    (root / "lerobot_pnp" / "stray.py").write_text('"""A module no layer names."""\n')
    with pytest.raises(SystemExit, match=r"no layer names \['stray'\]"):
        arch.layer_table(root)


def test_a_summary_is_the_docstrings_opening_as_markdown(arch, tmp_path):
    path = tmp_path / "m.py"
    path.write_text('"""``a|b``: short. Then a longer second sentence.\n\nA second paragraph."""\n')
    assert arch.summary(path, tmp_path) == "`a\\|b`: short. Then a longer second sentence."
    path.write_text('"""One sentence that is long enough to say what the module is. A second one."""\n')
    assert arch.summary(path, tmp_path) == "One sentence that is long enough to say what the module is."


def test_regenerating_keeps_the_prose_and_replaces_a_hand_edit():
    """Outside the markers the page is hand-written and stays; inside, a hand edit is replaced by the code's map."""
    dt = load_script("scripts/docs_tables.py")
    text = PAGE.read_text()
    edited = text.replace("## Data flow\n", "## Data flow\n\nA hand-written sentence.\n", 1)
    edited = edited.replace("| 2 | `report/` |", "| 2 | `reports/` |", 1)
    assert "`reports/`" in edited
    out = dt.render(PAGE, edited, {})
    assert "A hand-written sentence." in out and "`reports/`" not in out
    assert out.replace("\nA hand-written sentence.\n", "", 1) == text
