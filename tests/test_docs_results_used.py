"""docs/results/ holds only what a page shows or a script, test or benchmark reads.

A file there is used when some page (README.md, docs/**/*.md, mkdocs.yml) or some code (scripts/, tests/,
benchmarks/, lerobot_pnp/) names it: by its path from the repository root or from docs/results/, or by its path
relative to the naming file's folder (a page's link, a study report's ``figures/x.png``). A run's record, the
``eval_info.json`` or ``row.json`` that ``lerobot-eval`` and the leaderboard keep in a run folder, is used when
its folder, or the folder above it, is named (``lerobot-pnp compare`` and ``lerobot-pnp leaderboard`` read run
folders, a leaderboard row one per training seed, and their pages name the folders). A script that joins a folder it
names to a file name it names (``f"{folder}/protocol.json"``) reads that file. git keeps every removed record in its history.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = "docs/results/"
READERS = ("README.md", "mkdocs.yml", "docs", "scripts", "tests", "benchmarks", "lerobot_pnp")
RUN_RECORDS = ("eval_info.json", "row.json")


def _tracked(*paths: str) -> list[str]:
    return subprocess.check_output(["git", "ls-files", *paths], cwd=ROOT, text=True).split()


def _readers() -> dict[str, str]:
    """Every page and code file that may name a result file, by its path, with its text (the changelog is
    history, not a reader)."""
    out = {}
    for rel in _tracked(*READERS):
        if rel.endswith((".md", ".py", ".yml", ".json", ".sh")) and not rel.endswith("changelog.md"):
            out[rel] = (ROOT / rel).read_text(errors="replace")
    return out


def unused(files: list[str], readers: dict[str, str]) -> list[str]:
    """The files of ``files`` (paths from the repository root) that no reader names."""
    out = []
    for rel in files:
        short = rel.removeprefix(RESULTS)
        folder = os.path.dirname(short)
        named = any(rel in text or short in text for name, text in readers.items() if name != rel)
        named = named or any(
            os.path.relpath(rel, os.path.dirname(name)) in text for name, text in readers.items() if name != rel
        )
        if not named and os.path.basename(rel) in RUN_RECORDS and folder:
            parents = (folder, os.path.dirname(folder)) if "/" in folder else (folder,)
            named = any(p in text for p in parents for name, text in readers.items() if name != rel)
        if not named:  # a script that joins a folder it names to the file's name: f"{folder}/compare/compare.json"
            parts = short.split("/")
            splits = [("/".join(parts[:i]), "/".join(parts[i:])) for i in range(1, len(parts))]
            named = any(head in text and tail in text for head, tail in splits for text in readers.values())
        if not named:
            out.append(rel)
    return out


def test_every_file_under_docs_results_is_read_by_a_page_or_code():
    files = _tracked(RESULTS)
    assert len(files) > 100  # the results were listed
    assert unused(files, _readers()) == [], "nothing shows or reads these: link them from a page or git rm them"


def test_an_unread_file_is_found():
    readers = {"docs/results/index.md": "see [the figure](study/report_full/figures/a.png) and `runs/seed1`"}
    files = ["docs/results/study/report_full/figures/a.png", "docs/results/study/report_full/figures/b.png",
             "docs/results/runs/seed1/eval_info.json", "docs/results/runs/seed1/extra.json"]  # fmt: skip
    assert unused(files, readers) == [
        "docs/results/study/report_full/figures/b.png",
        "docs/results/runs/seed1/extra.json",
    ]
