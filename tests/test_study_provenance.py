"""The study's provenance: every summary records the machine (CPU model, cores) and the code (commit, date);
which of the study's code files differ between a summary's commit and a checkout
(``report.code_provenance``, ``benchmarks/study_provenance.py``), on a small git repository made here."""

import json
import shutil
import subprocess
from datetime import date
from pathlib import Path

import pytest
from clis import load_script

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.report.code_provenance import checkout_commit, study_code_changes
from lerobot_pnp.report.preamble import _code_sentence
from lerobot_pnp.report.provenance import code_identity, machine

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="needs git")


@pytest.fixture(scope="module")
def bench():
    return load_script("benchmarks/study_provenance.py")


def _git(repo: Path, *args: str) -> str:
    cmd = ["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@example.org", *args]
    return subprocess.run(cmd, check=True, capture_output=True, text=True).stdout.strip()


def _write(repo: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (repo / name).parent.mkdir(parents=True, exist_ok=True)
        (repo / name).write_text(text)


@pytest.fixture
def repo(tmp_path) -> tuple[Path, str, str]:
    """A repository of two commits: the first with a study's code, the second changing some of it."""
    repo = tmp_path / "repo"
    repo.mkdir()
    _git(repo, "init", "-q")
    _write(repo, {
        "lerobot_pnp/sim/physics.py": '"""Physics."""\nSTEP = 0.01\n',
        "lerobot_pnp/report/run.py": '"""Run."""\n\ndef f():\n    """Once."""\n    return 1  # one\n',
        "lerobot_pnp/viz/viewer.py": "COLOR = 1\n",
        "configs/report_full.json": '{"epochs": 300}\n',
        "README.md": "hello\n",
    })  # fmt: skip
    _git(repo, "add", "-A")
    _git(repo, "commit", "-qm", "one")
    first = _git(repo, "rev-parse", "HEAD")
    _write(repo, {
        "lerobot_pnp/sim/physics.py": '"""Physics."""\nSTEP = 0.002\n',  # the code
        "lerobot_pnp/report/run.py": '"""Run, again."""\n\ndef f():\n    """Twice."""\n    return 1  # two\n',  # text
        "lerobot_pnp/viz/viewer.py": "COLOR = 2\n",  # the viewer changes no number
        "README.md": "bye\n",
    })  # fmt: skip
    _git(repo, "commit", "-qam", "two")
    return repo, first, _git(repo, "rev-parse", "HEAD")


def test_the_study_code_that_changed_since_a_commit_is_named(repo):
    root, first, second = repo
    changes = study_code_changes(root, first)
    assert changes.changed == ("lerobot_pnp/sim/physics.py",) and not changes.same
    assert changes.text_only == ("lerobot_pnp/report/run.py",)
    assert study_code_changes(root, second).same
    # the work tree counts: an edited config and a new module not yet committed
    _write(root, {"configs/report_full.json": '{"epochs": 30}\n', "lerobot_pnp/sim/new.py": "X = 1\n"})
    assert study_code_changes(root, second).changed == ("configs/report_full.json", "lerobot_pnp/sim/new.py")


def test_a_missing_commit_or_repository_is_refused_in_one_line(repo, tmp_path):
    root, _, _ = repo
    with pytest.raises(ConfigError, match="commit '0123abc' is not in the repository"):
        study_code_changes(root, "0123abc")
    (tmp_path / "plain").mkdir()
    with pytest.raises(ConfigError, match="is not a git checkout"):
        study_code_changes(tmp_path / "plain", "0123abc")


def test_the_commit_is_recorded_only_at_the_top_of_a_checkout(repo):
    root, first, second = repo
    assert checkout_commit(root) == second
    assert checkout_commit(root / "lerobot_pnp") is None  # a copy inside another repository names no commit
    assert code_identity(root)["commit"] == second and code_identity(root)["uncommitted_changes"] is False
    _write(root, {"lerobot_pnp/sim/physics.py": "STEP = 1\n"})
    assert code_identity(root)["uncommitted_changes"] is True
    assert code_identity(root / "lerobot_pnp")["commit"] is None


def test_every_summary_records_the_machine_and_the_code():
    m = machine()
    assert m["cpu"] and m["cores_available"] >= 1
    assert date.fromisoformat(m["date"])
    assert {"commit", "uncommitted_changes", "lerobot_pnp"} <= m.keys()
    if checkout_commit(ROOT):  # a git checkout (CI clones one)
        assert m["commit"] == _git(ROOT, "rev-parse", "HEAD")


def test_the_benchmark_names_the_changed_files_from_the_summarys_commit_or_the_sources(bench, repo, capsys):
    root, first, second = repo
    recorded = root / "a.json"
    recorded.write_text(json.dumps({"success": {}, "machine": {"commit": first}}))
    unrecorded = root / "b.json"
    unrecorded.write_text(json.dumps({"success": {}, "machine": {}}))
    sources = root / "sources.json"
    sources.write_text(json.dumps({"study": {"files": ["b.json"], "commit": second}}))
    assert bench.main([str(recorded), "--root", str(root), "--sources", str(sources)]) == 1
    assert "  changed: lerobot_pnp/sim/physics.py" in capsys.readouterr().out
    assert bench.main([str(unrecorded), "--root", str(root), "--sources", str(sources)]) == 0
    assert f"made at {second}; study code changed since in 0 files" in capsys.readouterr().out
    sources.write_text("{}")
    assert bench.main([str(unrecorded), "--root", str(root), "--sources", str(sources)]) == 2
    assert "names no commit" in capsys.readouterr().err


def test_the_report_names_the_commit_where_the_summary_records_it():
    mach = {"commit": "0123456789abcdef", "uncommitted_changes": True, "date": "2026-12-07"}
    assert _code_sentence(mach) == (
        " Code: commit `0123456789ab` with uncommitted changes to the study's code, run on 2026-12-07."
    )
    assert _code_sentence({"cpu": "a summary written before the commit was recorded"}) == ""


def test_the_published_study_was_made_by_the_code_that_ships(bench):
    """The committed study (its summaries, reports and figures) is the output of this checkout's study code (the
    package apart from the viewer, the two study configs, the lock file; docstrings and comments aside), read
    from the digests recorded from the checkout it ran in, so a clone without history checks it too. A change to
    that code fails here until the study is rerun and committed with its record."""
    record = json.loads(bench.CODE_RECORD.read_text())
    for summary in bench.SUMMARIES:
        assert json.loads(summary.read_text())["machine"]["commit"] == record["commit"], summary
    changed = bench.code_changes(record, ROOT)
    assert not changed, (
        f"the published study was made at {record['commit'][:12]}, and its code has changed since in "
        f"{', '.join(changed)}: rerun `make study`, copy outputs/{{report_full,heldout}} into docs/results/study/ "
        "and record the code (python benchmarks/study_provenance.py --record .)"
    )


def test_the_code_record_tells_a_code_change_from_a_docstring_change(bench, repo, tmp_path):
    root, first, second = repo
    _git(root, "checkout", "-q", first)
    record = bench.record_code(root, tmp_path / "code.json")
    assert record["commit"] == first and json.loads((tmp_path / "code.json").read_text()) == record
    assert set(record["files"]) == {
        "lerobot_pnp/sim/physics.py",
        "lerobot_pnp/report/run.py",
        "configs/report_full.json",
    }
    _git(root, "checkout", "-q", second)
    assert bench.code_changes(record, root) == ["lerobot_pnp/sim/physics.py"]  # run.py's docstrings alone changed
    _write(root, {"lerobot_pnp/sim/new.py": "X = 1\n"})
    assert bench.code_changes(record, root) == ["lerobot_pnp/sim/new.py", "lerobot_pnp/sim/physics.py"]
    with pytest.raises(ConfigError, match="not the top of a git checkout"):
        bench.record_code(root / "lerobot_pnp", tmp_path / "other.json")
