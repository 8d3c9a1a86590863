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
    jobs, times, cli, _ = bench.summary_jobs(summary, 0)
    assert cli == 7.0 and len(jobs) == 6 and sum(times.values()) == 225.0
    n10 = next(j for j in jobs if j.tag == "n10" and j.part == TRAINING)
    assert n10.n_demos == 10
    # two cores: the 100 s training and the expert start; the n10 run follows the expert (40 -> 60, then 65);
    # the clocked net's two suites wait for its training (100 -> 130 on both cores)
    assert bench.replay(jobs, times, 2) == pytest.approx(130.0)
    assert bench.replay(jobs, times, 1) == pytest.approx(225.0)


def test_the_cross_check_replays_as_a_pool_job_after_the_nominal_evaluation(bench, tmp_path):
    """The study runs its cross-check in the pool once the nominal evaluation it compares with is recorded: on
    one core beside the other suite, not after the pool; a summary without its config replays it after."""
    timings = {"train/clocked_lstm/1000": 100.0, "eval/clocked_lstm/1000/nominal": 10.0,
               "eval/clocked_lstm/1000/nudge_0.03": 30.0, "eval/expert/-/nominal": 40.0, "cli_check": 15.0}  # fmt: skip
    config = {"methods": ["expert", "clocked_lstm"], "train_seeds": [1000], "cli_check_episodes": 5}
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps({"timings_s": timings, "config": config}))
    # 100 s training; then its nominal (10 s) and the other suite (30 s) side by side; the cross-check after the
    # nominal one (110 -> 125) beside the other suite (-> 130)
    assert bench.replay_studies([summary]) == {"jobs": 5, "train_s": 100.0, "eval_s": 95.0, "pool_s": 130.0,
                                               "serial_s": 0.0}  # fmt: skip
    after = bench.replay_studies([summary], cli_in_pool=False)
    assert (after["pool_s"], after["serial_s"]) == (130.0, 15.0)
    summary.write_text(json.dumps({"timings_s": timings}))
    assert bench.replay_studies([summary])["serial_s"] == 15.0


def test_a_cut_replays_without_its_methods_jobs_and_with_its_training_scale(bench, tmp_path, capsys):
    """``--without STUDY:METHOD`` leaves that study's method out (the other study's stays); ``--train-scale`` scales
    every training; a malformed ``--without`` is one line naming the form."""
    timings = {"train/clocked_lstm/1000": 100.0, "eval/clocked_lstm/1000/nominal": 30.0, "eval/expert/-/nominal": 40.0}
    for name in ("a", "b"):
        (tmp_path / f"{name}.json").write_text(json.dumps({"timings_s": timings}))
    studies = [tmp_path / "a.json", tmp_path / "b.json"]
    whole = bench.replay_studies(studies, processes=1)
    assert (whole["jobs"], whole["pool_s"]) == (6, 340.0)
    cut = bench.replay_studies(studies, processes=1, without=((1, "clocked_lstm"),), train_scale=0.5)
    assert (cut["jobs"], cut["train_s"], cut["pool_s"]) == (4, 50.0, 50.0 + 30.0 + 40.0 + 40.0)
    bench.main(["--study", str(studies[0]), "--without", "0:expert"])
    assert "2 jobs: training 100 s + evaluation 30 s" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="--without takes STUDY:METHOD"):
        bench.main(["--study", str(studies[0]), "--without", "expert"])
