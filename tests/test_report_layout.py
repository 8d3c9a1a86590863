"""``StudyLayout`` returns exactly the paths the study has always used: the caches are found by them, so a
renamed path would silently retrain and re-evaluate everything (or orphan an older study's results)."""

from __future__ import annotations

import json

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


def test_an_older_study_is_recognised_by_what_its_entries_hold(tmp_path):
    """``--fresh`` on a study folder without a manifest deletes the entries ``written_by_the_study`` proves are
    the study's: each layout name, as the study writes it; the same names without that content, or as links,
    are not claimed."""
    layout = StudyLayout(tmp_path / "s")
    record = json.dumps({"key": "k", "parts": {"stage": "dataset"}})
    for path in (layout.config, layout.report, layout.summary, layout.train("m", "1") / "stage.json",
                 layout.eval_record("m", "1", "nominal"), layout.cli_check / "stage.json",
                 layout.dataset() / "stage.json", layout.dataset("dense") / "meta" / "pnp_generate.json",
                 layout.figure("a.png")):  # fmt: skip
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(record)
    layout.dataset("dense").joinpath("meta", "pnp_generate.json").write_text(
        json.dumps({"generation": {"repo_id": "local/dataset_dense"}})
    )
    layout.summary.write_text(json.dumps({"figures": ["a.png"]}))
    names = (*layout.stage_names(), *layout.report_names(), layout.dataset("dense").name)
    assert all(written_by_the_study(layout.out / n) for n in names), names
    for name in ("dataset_mine", "train_old", "figures_x", "notes.txt"):
        (layout.out / name).mkdir()
        assert not written_by_the_study(layout.out / name)
    (layout.out / "dataset_link").symlink_to(layout.dataset(), target_is_directory=True)
    assert not written_by_the_study(layout.out / "dataset_link")
    layout.figure("b.png").write_text("not drawn by the study")
    assert not written_by_the_study(layout.figures)
    assert set(layout.stage_names()) == {"study_config.json", "dataset", "train", "evals", "lerobot_eval_cli"}
    assert set(layout.report_names()) == {"report.md", "summary.json", "figures"}
