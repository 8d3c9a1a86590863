"""What a study run costs, recorded by the run itself (``report.cost``): wall clock, CPU, memory and disk per
stage, and whether the run did every stage itself; the cross-check as a job of the pool."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from unittest import mock

import pytest
from clis import load_script

from lerobot_pnp.report import cost
from lerobot_pnp.report.cross_check import cli_job
from lerobot_pnp.report.methods import get_methods
from lerobot_pnp.report.schedule import CLI_CHECK, TRAINING, Job


def test_the_meter_adds_up_each_stage_and_a_run_that_found_a_stage_done_is_not_from_scratch(tmp_path):
    out, outside = tmp_path / "study", tmp_path / "outside"
    out.mkdir(), outside.mkdir()
    meter = cost.CostMeter([out])
    (out / "dataset.bin").write_bytes(os.urandom(1 << 20))
    (outside / "big.bin").write_bytes(os.urandom(4 << 20))
    (out / "link").symlink_to(outside / "big.bin")  # counted as a link, never followed
    meter.stage("datasets")
    for _ in range(2):  # each study's cross-check in turn: one stage, its walls added up
        time.sleep(0.05)
        meter.stage("cli_check")
    meter.count("trainings", 1, 1)
    meter.count("evaluations", 3, 4)  # one evaluation found on disk
    record = meter.record()
    assert list(record["stages"]) == ["datasets", "cli_check"]
    assert 1.0 <= record["stages"]["datasets"]["disk_mb"] < 2.0 and 1.0 <= record["disk_mb"] < 2.0
    assert record["stages"]["cli_check"]["wall_s"] >= 0.1
    assert record["wall_s"] >= sum(s["wall_s"] for s in record["stages"].values()) - 0.2
    assert record["ran"] == {"trainings": [1, 1], "evaluations": [3, 4]} and record["from_scratch"] is False
    meter = cost.CostMeter([out])
    meter.count("evaluations", 4, 4)
    assert meter.record()["from_scratch"] is True


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="reads /proc")
def test_the_sampler_counts_the_memory_and_cpu_of_the_processes_the_run_started():
    sampler = cost.TreeSampler(interval=0.05)
    # it spends 0.5 s of CPU, then idles alive for a second: a sample sees that CPU however busy the machine is
    child = subprocess.Popen([sys.executable, "-c", "import time\nx = bytearray(300 << 20)\n"
                              "while time.process_time() < 0.5: pass\ntime.sleep(1.0)"])  # fmt: skip
    child.wait()
    peak_mb, cpu_s = sampler.lap()
    sampler.stop()
    assert peak_mb >= 250 and cpu_s > 0.1  # its 300 MB, and the CPU it spent before its idle second


def test_the_cross_check_is_a_pool_job_after_the_nominal_evaluation_it_is_compared_with():
    from lerobot_pnp.report.config import StudyConfig

    cfg = StudyConfig(preset="quick", cli_check_episodes=5, methods=["lookup_table", "clocked_lstm"])
    methods = get_methods(cfg.methods)
    jobs = [Job("clocked_lstm", "1000", None, TRAINING), Job("clocked_lstm", "1000", None, "nominal")]
    job = cli_job(cfg, methods, 0, jobs)
    assert job == Job("clocked_lstm", "1000", None, CLI_CHECK) and job.after() == jobs[1].key
    assert cli_job(cfg, methods, 0, jobs[:1]) is None  # no nominal evaluation in the pool: run after it
    cfg.report_only = True
    assert cli_job(cfg, methods, 0, jobs) is None


def _stage(wall_s: float) -> dict:
    return {"wall_s": wall_s, "cpu_s": 1.5 * wall_s, "peak_rss_mb": 2048.0, "disk_mb": 3072.0}


def _summary(path: Path, from_scratch: bool) -> Path:
    """A study's summary.json: its job times (a 100 s training, then its nominal evaluation and the cross-check;
    the expert beside them) and its cost record."""
    timings = {"train/clocked_lstm/1000": 100.0, "eval/clocked_lstm/1000/nominal": 10.0,
               "eval/expert/-/nominal": 40.0, "cli_check": 5.0}  # fmt: skip
    config = {"methods": ["expert", "clocked_lstm"], "train_seeds": [1000], "cli_check_episodes": 5}
    record = {"wall_s": 240.0, "cpu_s": 360.0, "peak_rss_mb": 2048.0, "job_rss_mb": 600.0, "disk_mb": 3072.0,
              "processes": 2, "stages": {"datasets": _stage(90.0), "jobs": _stage(118.0), "cli_check": _stage(2.0),
              "report": _stage(20.0)}, "ran": {"datasets": [1, 1], "trainings": [1, 1], "evaluations": [2, 2]},
              "from_scratch": from_scratch, "studies": ["s"], "memory_how": "summed"}  # fmt: skip
    machine = {"cpu": "AMD EPYC", "cores_available": 2, "lerobot": "0.6.1", "torch": "2.11", "mujoco": "4.0.1",
               "commit": "abcdef1234", "date": "2027-01-02"}  # fmt: skip
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"timings_s": timings, "config": config, "cost": record, "machine": machine}))
    return path


def test_the_benchmark_puts_the_measured_pool_beside_its_replay_and_refuses_a_resumed_run(tmp_path):
    bench = load_script("benchmarks/study_cost.py")
    rows, record = bench.compare([_summary(tmp_path / "summary.json", True)])
    parts = {part: (measured, replayed) for part, measured, replayed in rows}
    # the replay: the training and the expert side by side, then the nominal evaluation, then the cross-check
    assert parts["trainings and evaluations: one pool of 2"] == (118.0, 115.0)
    assert parts["whole run"] == (240.0, 90.0 + 20.0 + 115.0) and record["job_s"] == 155.0
    with mock.patch.object(sys, "argv", ["study_cost.py", "--study", str(tmp_path / "summary.json")]):
        assert bench.main() == 0
    _summary(tmp_path / "summary.json", False)
    with mock.patch.object(sys, "argv", ["study_cost.py", "--study", str(tmp_path / "summary.json")]):
        assert bench.main() == 1  # a resumed run's wall clock is not the study's cost


def test_the_docs_state_the_cost_from_the_record_and_say_when_there_is_none(tmp_path, monkeypatch):
    docs = load_script("scripts/docs_cost.py")
    monkeypatch.setattr(docs, "RESULTS", tmp_path)
    machine = {"cpu": "AMD EPYC", "cores_available": 2, "lerobot": "0.6.1", "torch": "2", "mujoco": "3",
               "commit": "1234567abc", "date": "2027-01-01"}  # fmt: skip
    (tmp_path / "make_costs.json").write_text(
        json.dumps({"machine": machine, "targets": {"make demo": {"wall_s": 466}}})
    )
    (tmp_path / "sources.json").write_text(json.dumps({"study": {
        "files": ["study/summary.json"], "commit": "0000000", "date": "2026-01-01"}}))  # fmt: skip
    _summary(tmp_path / "study" / "summary.json", True)
    line, table = docs.cost_lines(""), docs.cost_table("")
    assert "`make demo`: **7 min 46 s** from a fresh clone" in line and "commit `1234567`, 2027-01-01" in line
    assert (
        "`make study`: **4 min** from scratch on AMD EPYC, 2 cores" in line and "commit `abcdef1`, 2027-01-02" in line
    )
    assert "| **whole run** | **4 min** | 1.5 | 2.0 GB | 3.0 GB |" in table
    assert "(datasets 1, trainings 1, evaluations 2, every one made by this run)" in table
    _summary(tmp_path / "study" / "summary.json", False)  # a resumed run: the replay, labelled as one
    line, table = docs.cost_lines(""), docs.cost_table("")
    assert "**not yet measured from scratch**" in line and "replay to 2 min on 2 processes" in line
    assert "| both, side by side in one pool | 3 min | 2 min |" in table and "Replayed" in table
