"""``StudyLayout`` returns exactly the paths the study has always used: the caches are found by them, so a
renamed path would silently retrain and re-evaluate everything (or orphan an older study's results)."""

from __future__ import annotations

from pathlib import Path

from lerobot_pnp.report.layout import StudyLayout
from lerobot_pnp.report.stages import written_by_the_study


def test_every_study_path_is_todays_literal(tmp_path):
    out = tmp_path / "study"
    layout = StudyLayout(out)
    assert layout.config == out / "study_config.json"
    assert layout.dataset() == layout.dataset("keyframe") == out / "dataset"
    assert layout.dataset("dense") == out / "dataset_dense"
    assert layout.dataset("phase") == out / "dataset_phase"
    assert layout.train("clocked_lstm", "1000") == out / "train/clocked_lstm/seed1000"
    assert layout.train("lookup_table", "n30") == out / "train/lookup_table/seedn30"
    assert layout.eval_record("lookup_table", "-", "nudge_0.03") == out / "evals/lookup_table/seed-/nudge_0.03.json"
    assert layout.cli_check == out / "lerobot_eval_cli/nominal"
    assert layout.figure("recovery.png") == out / "figures/recovery.png"
    assert layout.report == out / "report.md"
    assert layout.summary == out / "summary.json"


def test_the_manifest_names_are_what_an_older_study_is_recognised_by():
    """``--fresh`` on a study folder without a manifest deletes the entries ``written_by_the_study`` knows."""
    layout = StudyLayout(Path("x"))
    names = (*layout.stage_names(), *layout.report_names(), layout.dataset("dense").name)
    assert all(written_by_the_study(n) for n in names), names
    assert set(layout.stage_names()) == {"study_config.json", "dataset", "train", "evals", "lerobot_eval_cli"}
    assert set(layout.report_names()) == {"report.md", "summary.json", "figures"}
