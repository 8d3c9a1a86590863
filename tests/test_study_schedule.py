"""The study-time replay (``benchmarks/study_schedule.py``): a summary's recorded times replay through the
study's own scheduler, an evaluation after its training, data-efficiency runs and the cross-check counted."""

import json

import pytest
from clis import load_script

from lerobot_pnp.report.schedule import TRAINING


@pytest.fixture(scope="module")
def bench():
    return load_script("benchmarks/study_schedule.py")


def test_a_summary_replays_every_recorded_job_in_the_pools_order(bench, tmp_path):
    timings = {
        "dataset": 0.1,
        "train/clocked_lstm/1000": 100.0,
        "eval/clocked_lstm/1000/nominal": 30.0,
        "eval/clocked_lstm/1000/nudge_0.03": 30.0,
        "eval/expert/-/nominal": 40.0,
        "train/clocked_lstm/n10": 20.0,  # a data-efficiency run: its training and evaluation count too
        "eval/clocked_lstm/n10/nominal": 5.0,
        "cli_check": 7.0,
        "run/wall_clock": 1.0,
    }
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps({"timings_s": timings}))
    jobs, times, cli = bench.summary_jobs(summary, 0)
    assert cli == 7.0 and len(jobs) == 6 and sum(times.values()) == 225.0
    n10 = next(j for j in jobs if j.tag == "n10" and j.part == TRAINING)
    assert n10.n_demos == 10
    # two cores: the 100 s training and the expert start; the n10 run follows the expert (40 -> 60, then 65);
    # the clocked net's two suites wait for its training (100 -> 130 on both cores)
    assert bench.replay(jobs, times, 2) == pytest.approx(130.0)
    assert bench.replay(jobs, times, 1) == pytest.approx(225.0)
