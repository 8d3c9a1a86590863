"""What every command costs (docs/costs.md): the committed record measures the README's quick start as it is written
now, names the machine it ran on, and the benchmark measures what a command writes and refuses a failed run."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

import pytest
from clis import load_script

ROOT = Path(__file__).resolve().parents[1]
RECORD = ROOT / "docs" / "results" / "command_costs.json"


@pytest.fixture(scope="module")
def bench():
    return load_script("benchmarks/command_costs.py")


@pytest.fixture(scope="module")
def tables():
    load_script("scripts/docs_tables.py")  # puts scripts/ on the path
    import docs_command_costs

    return docs_command_costs


def test_the_record_measures_the_readmes_quick_start_as_written(bench):
    """A changed quick start (another size, another command) needs the benchmark run again."""
    record = json.loads(RECORD.read_text())
    commands = bench.quickstart_commands((ROOT / "README.md").read_text())
    assert [c["command"] for c in record["commands"]] == [shlex.join(c) for c in commands]
    for c in record["commands"]:
        assert c["wall_s"] > 0 and c["cpu_s"] > 0 and c["peak_rss_mb"] > 0 and c["disk_mb"] >= 0, c
    machine = record["machine"]
    assert machine["cpu"] and machine["cores_available"] >= 1 and len(machine["commit"]) >= 7


def test_a_command_is_measured_and_a_failed_one_refused(bench, tmp_path):
    """What it writes to its folder and the memory its process tree holds (the tree sampler: ``os.wait4``'s peak
    also holds this test process's own resident set, which Linux records when the command starts)."""
    python = Path(sys.executable).name
    code = "import time; b = b'y' * 300_000_000; open('f', 'wb').write(b'x' * 3_000_000); time.sleep(1)"
    row = bench.run_command([python, "-c", code], tmp_path, tmp_path / "log")
    assert 2.5 < row["disk_mb"] < 3.5, row
    assert row["peak_tree_rss_mb"] > 250 and row["peak_rss_mb"] >= row["peak_tree_rss_mb"] - 50, row
    assert row["wall_s"] >= 1, row
    with pytest.raises(SystemExit, match="exited 3"):
        bench.run_command([python, "-c", "raise SystemExit(3)"], tmp_path, tmp_path / "log")


def test_the_page_states_the_records_numbers(tables):
    record = json.loads(RECORD.read_text())
    text = tables.command_costs("results/")
    for c in record["commands"]:
        assert (
            f"| {tables.duration(c['wall_s'])} | {tables.duration(c['cpu_s'])} | {tables.size(c['peak_rss_mb'])}"
            in text
        )
    assert record["machine"]["commit"][:7] in text
    assert [tables.duration(s) for s in (14.4, 185, 4330)] == ["14 s", "3 min 5 s", "1 h 12 min"]
    assert [tables.size(m) for m in (1.14, 973.4, 1579.6, None)] == ["1.1 MB", "973 MB", "1.5 GB", "-"]


def test_make_study_is_filled_from_the_studys_cost_record_once_it_has_one(tables, monkeypatch):
    import docs_cost

    summary = json.loads((ROOT / "docs/results/study/report_full/summary.json").read_text())
    monkeypatch.setattr(docs_cost, "_study", lambda: ({}, [summary]))
    summary.pop("cost", None)
    assert tables.study_cost() is None
    assert "| `make study` | not measured from scratch |" in tables.make_costs("results/")
    summary["cost"] = {
        "wall_s": 4000.0,
        "cpu_s": 7500.0,
        "peak_rss_mb": 12900.0,
        "disk_mb": 2048.0,
        "from_scratch": False,
    }
    assert tables.study_cost() is None  # a resumed run's wall clock is not the study's cost
    summary["cost"]["from_scratch"] = True
    assert tables.study_cost()[:3] == ("1 h 07 min", "12.6 GB", "2.0 GB")
    assert "| `make study` | 1 h 07 min | 2 h 5 min | 12.6 GB | 2.0 GB |" in tables.make_costs("results/")


def test_the_make_targets_come_from_their_fresh_clone_record(tables, monkeypatch, tmp_path):
    """`make install`, `make test` and `make demo`: one row each from ``make_costs.json``, with the test summary and
    whether SLURM's tests ran; a changed record changes the table."""
    record = json.loads((ROOT / "docs/results/make_costs.json").read_text())
    record["targets"]["make test"].update(wall_s=299.6, tests="1000 passed, 3 skipped")
    record["slurm"] = False
    (tmp_path / "make_costs.json").write_text(json.dumps(record))
    monkeypatch.setattr(tables, "RESULTS", tmp_path)
    table = tables.make_costs("results/")
    assert "| `make test` | 5 min 0 s |" in table and "(1000 passed, some skipped)" in table
    assert "SLURM absent, so its tests skipped" in table and "| `make install` |" in table
