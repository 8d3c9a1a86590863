"""Whether the committed study summaries were made by the code that ships: the study's code files
(``lerobot_pnp.report.code_provenance.STUDY_CODE``) that differ between the commit each summary names and this
checkout.

    python benchmarks/study_provenance.py [SUMMARY.json ...] [--root .] [--sources docs/results/sources.json]

A summary names its commit in ``machine.commit`` (written by the study since it records it); a summary that
does not is looked up in ``--sources`` (the entry whose ``files`` lists it, relative to that file's folder).
Prints, per summary, its commit and the files whose code changed since (and those whose docstrings or
comments alone changed). Exit status 0 when every summary's code is the checkout's, 1 when some changed, 2
when a commit is not named or not in the repository (a shallow clone) or git is missing.

    python benchmarks/study_provenance.py --record STUDY_CHECKOUT   # writes docs/results/study/code.json

``--record`` writes the digest of every study code file of the checkout a study ran in (``code.json``: the
commit and, per file, the sha256 of its code with docstrings and comments set aside), so that a checkout can be
compared with the published study without git history (``code_changes``; ``tests/test_study_provenance.py``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from lerobot_pnp.errors import ConfigError, PnPError
from lerobot_pnp.outputs import write_json_atomic
from lerobot_pnp.report.code_provenance import SOURCE_ROOT, checkout_commit, code_digests, study_code_changes
from lerobot_pnp.report.repro import load_summary

RESULTS = SOURCE_ROOT / "docs" / "results"
SUMMARIES = (RESULTS / "study" / "report_full" / "summary.json", RESULTS / "study" / "heldout" / "summary.json")
CODE_RECORD = RESULTS / "study" / "code.json"


def code_changes(record: dict, root: Path) -> list[str]:
    """The study code files whose code differs between the recorded study checkout and ``root``: changed,
    added or removed since."""
    now, then = code_digests(root), record["files"]
    return sorted(name for name in now.keys() | then.keys() if now.get(name) != then.get(name))


def record_code(checkout: Path, out: Path = CODE_RECORD) -> dict:
    """Write ``out``: the commit of the study ``checkout`` and its study code files' digests."""
    commit = checkout_commit(checkout)
    if commit is None:
        raise ConfigError(f"{checkout} is not the top of a git checkout: the study's commit cannot be named")
    record = {"commit": commit, "files": code_digests(checkout)}
    write_json_atomic(out, record)
    return record


def summary_commit(path: Path, sources: Path) -> str:
    """The commit that made the summary at ``path``: its own record, else the ``sources`` entry listing it."""
    commit = load_summary(path).get("machine", {}).get("commit")
    if commit:
        return commit
    try:
        entries = json.loads(sources.read_text())
    except (OSError, ValueError):
        entries = {}
    for entry in entries.values():
        files = [(sources.parent / f).resolve() for f in entry.get("files", [])] if isinstance(entry, dict) else []
        if Path(path).resolve() in files and entry.get("commit"):
            return entry["commit"]
    raise ConfigError(f"{path} names no commit, and {sources} lists no commit for it")


def describe(path: Path, root: Path, sources: Path) -> tuple[bool, list[str]]:
    """Whether the summary's study code is the checkout's, and the lines that say which files changed."""
    commit = summary_commit(path, sources)
    changes = study_code_changes(root, commit)
    lines = [f"{path}: made at {commit}; study code changed since in {len(changes.changed)} files"]
    lines += [f"  changed: {f}" for f in changes.changed]
    lines += [f"  docstrings or comments only: {f}" for f in changes.text_only]
    return changes.same, lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("summaries", nargs="*", type=Path, default=list(SUMMARIES))
    parser.add_argument("--root", type=Path, default=SOURCE_ROOT, help="the checkout to compare (its work tree)")
    parser.add_argument("--sources", type=Path, default=RESULTS / "sources.json")
    parser.add_argument("--record", type=Path, help="write code.json from the checkout the study ran in")
    args = parser.parse_args(argv)
    same = True
    try:
        if args.record:
            record = record_code(args.record)
            print(f"{CODE_RECORD}: {len(record['files'])} study code files of {record['commit']}")
            return 0
        for path in args.summaries:
            ok, lines = describe(path, args.root, args.sources)
            same = same and ok
            print("\n".join(lines))
    except PnPError as e:
        print(f"study_provenance: {e}", file=sys.stderr)
        return 2
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
