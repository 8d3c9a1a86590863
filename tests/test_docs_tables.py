"""The README's and the docs' generated tables equal what their sources give today.

Every result table is regenerated from the committed summaries under docs/results/ and every reference table
from the code (suite catalogue, CLI help, config fields); a page that differs means a source changed without
``python scripts/docs_tables.py`` being run, or a page was edited by hand inside a generated block.
"""

import re
from pathlib import Path

import pytest
import yaml
from clis import load_script

ROOT = Path(__file__).resolve().parents[1]


def _docs_tables():
    return load_script("scripts/docs_tables.py")


@pytest.fixture(scope="module")
def regenerated():
    return _docs_tables().regenerate()


def test_every_generated_block_matches_its_source(regenerated):
    stale = [str(p.relative_to(ROOT)) for p, (old, new) in regenerated.items() if old != new]
    assert not stale, f"run `python scripts/docs_tables.py`: generated blocks differ in {stale}"


def test_every_block_is_used_and_the_headline_pages_hold_theirs(regenerated):
    dt = _docs_tables()
    used = {name for old, _ in regenerated.values() for name in re.findall(r"<!-- begin generated: ([\w-]+) -->", old)}
    assert used == set(dt.BLOCKS)
    readme = (ROOT / "README.md").read_text()
    for name in ("paper-table", "heldout-verdicts", "cost"):
        assert f"<!-- begin generated: {name} -->" in readme


def test_a_hand_edited_number_is_caught():
    dt = _docs_tables()
    page = ROOT / "README.md"
    text = page.read_text()
    block = re.search(r"<!-- begin generated: heldout-verdicts -->\n(.*?)<!-- end", text, re.S).group(1)
    edited = text.replace(block, block.replace("%", " percent", 1))
    assert edited != text
    assert dt.render(page, edited, {}) == dt.render(page, text, {})


def test_an_unknown_block_is_an_error():
    dt = _docs_tables()
    with pytest.raises(SystemExit, match="unknown generated block 'nope'"):
        dt.render(ROOT / "README.md", "<!-- begin generated: nope -->\nx\n<!-- end generated: nope -->\n", {})


def test_every_result_table_names_its_run(regenerated):
    for name in ("paper-table", "heldout-verdicts", "heldout-suites", "gate-table", "memory-table", "planner-table"):
        text = _docs_tables().BLOCKS[name]("docs/results/")
        assert re.search(r"commit `[0-9a-f]{7,}`, \d{4}-\d{2}-\d{2}", text), name


def _nav_pages(nav) -> list[str]:
    out = []
    for item in nav:
        value = next(iter(item.values())) if isinstance(item, dict) else item
        out += _nav_pages(value) if isinstance(value, list) else [value]
    return out


REPRO = "results/study/repro.md"  # the study's rerun table


def test_the_site_nav_holds_every_page():
    """mkdocs --strict fails on a page off the nav (make test builds it); this names the page without a build. The
    exceptions, mkdocs' ``not_in_nav``: the pages ``lerobot-pnp compare`` wrote for the camera planner, which its
    page links instead (the next test), and the study's rerun table, which the page on reproducing it links."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    nav = set(_nav_pages(config["nav"]))
    pages = {str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md")}
    assert config["not_in_nav"].split() == ["/results/*/compare*/compare.md", f"/{REPRO}"]
    assert "(study/repro.md)" in (ROOT / "docs" / "results" / "reproduce.md").read_text()
    assert pages - nav - set(_compare_pages()) - {REPRO} == set(), "pages missing from mkdocs.yml's nav"
    assert nav - pages == set(), "nav entries without a page"
    assert nav & set(_compare_pages()) == set()


def _compare_pages() -> list[str]:
    return sorted(str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs" / "results").glob("*/compare*/compare.md"))


def test_results_has_at_most_six_nav_entries_and_every_comparison_is_linked_from_the_camera_planner():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    results = next(item["Results"] for item in config["nav"] if isinstance(item, dict) and "Results" in item)
    assert len(results) <= 6, results
    page = (ROOT / "docs" / "results" / "pixel_planner.md").read_text()
    linked = set(re.findall(r"\]\(([\w./-]+/compare\.md)\)", page.split("## Every comparison")[1]))
    assert len(_compare_pages()) >= 13
    assert {c.removeprefix("results/") for c in _compare_pages()} == linked


def test_readme_is_a_front_door_and_its_links_resolve():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 200
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
        if not target.startswith(("http://", "https://")):
            assert (ROOT / target).exists(), f"README links to a missing file: {target}"
