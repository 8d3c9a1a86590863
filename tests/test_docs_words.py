"""What users read names the software, not how it was worked on: no work sessions and no issue numbers in the
README, the documentation (pages and result files) or the package's code and docstrings."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROCESS_WORDS = re.compile(r"\bsessions?\b|\bissue\s*#?\s*\d+", re.IGNORECASE)
# an upstream project's tracker is a reference, not the story of this one
UPSTREAM = re.compile(r"\b(?:lerobot|mujoco|rerun|datatrove|draccus|torch|gymnasium)\s+issue\s*#?\s*\d+", re.IGNORECASE)
TEXT_SUFFIXES = {".md", ".py", ".json", ".txt", ".yml", ".yaml", ".toml"}


def _files() -> list[Path]:
    trees = [ROOT / "docs", ROOT / "lerobot_pnp"]
    found = [p for tree in trees for p in tree.rglob("*") if p.is_file() and p.suffix in TEXT_SUFFIXES]
    return [ROOT / "README.md", ROOT / "mkdocs.yml", *sorted(found)]


def offending_lines(paths: list[Path]) -> list[str]:
    out = []
    for path in paths:
        for i, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if PROCESS_WORDS.search(UPSTREAM.sub("", line)):
                out.append(
                    f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path.name}:{i}: {line.strip()[:120]}"
                )
    return out


def test_no_process_words_in_readme_docs_or_package():
    hits = offending_lines(_files())
    assert not hits, "words about how the project was worked on:\n" + "\n".join(hits)


def test_the_pattern_catches_what_it_must_and_spares_the_rest(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "a later session\nSessions of work\nsee issue 19\nIssue #7\nthe issue's target\nlerobot issue #4647\n"
    )
    hits = offending_lines([page])
    assert [h.split(": ", 1)[1] for h in hits] == ["a later session", "Sessions of work", "see issue 19", "Issue #7"]
