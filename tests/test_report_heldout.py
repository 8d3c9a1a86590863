"""The held-out-disturbance protocol as a study: the study's task (``task_preset``), the ``heldout``
preset, the methods refused up front on a task they cannot train on, and the per-axis report on a tiny study."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from lerobot_pnp.cache import Stage, code_versions
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.report import methods
from lerobot_pnp.report.config import StudyConfig, SuiteSpec
from lerobot_pnp.report.stages import dataset_parts
from lerobot_pnp.sim.suites import HELD_OUT_AXES, PROTOCOL_SUITES


def test_a_paper_study_keeps_its_stage_keys(tmp_path):
    """The new field leaves every key of a paper study as it was: its datasets, trainings and evaluations are
    reused. The dataset's key before the field existed is the literal below."""
    before = {"stage": "dataset", "num_episodes": 300, "seed": 0, "changes": {}, "versions": code_versions()}
    paper = StudyConfig(preset="quick")
    full = StudyConfig(preset="quick", task_preset="full", methods=["recovering"])
    assert paper.task_preset == "paper"
    key = Stage(tmp_path / "s.json", dataset_parts(paper)).key
    assert key == Stage(tmp_path / "s.json", before).key
    assert key != Stage(tmp_path / "s.json", dataset_parts(full)).key
    (rec,) = methods.get_methods(["recovering"])
    ctx = methods.TrainContext(tmp_path, tmp_path / "train", 1000, 2, data_keys={"keyframe": key})
    untold = methods.train_stage(rec, ctx).key  # the context before it carried the task's budget
    assert methods.train_stage(rec, replace(ctx, task_budget=10)).key == untold  # the paper task's
    widened = methods.train_stage(rec, replace(ctx, task_budget=40))  # the full task's
    assert widened.key != untold and widened.parts["overrides"]["max_episode_length"] == 41


def test_the_heldout_preset_runs_the_protocol_on_the_full_task():
    cfg = StudyConfig(preset="heldout")
    assert (cfg.task_preset, cfg.num_episodes, cfg.epochs, cfg.train_seeds) == ("full", 1000, 300, [1000, 1001, 1002])
    assert cfg.methods == ["expert", "lookup_table", "recovering", "act"]
    assert [s.name for s in cfg.suites] == ["nominal", *PROTOCOL_SUITES] and {s.n_episodes for s in cfg.suites} == {200}
    assert set(PROTOCOL_SUITES) == {s for a in HELD_OUT_AXES for s in a.in_distribution + a.held_out}
    assert cfg.cli_check_episodes == 100 and cfg.data_efficiency == []
    for preset in ("demo", "quick", "full"):
        assert StudyConfig(preset=preset).task_preset == "paper"


def test_make_demo_runs_the_paper_demo_then_the_recovery_headline():
    """make demo's two configs, run in one pool: the paper study and the held-out study cut to one seed and four suites (a
    training condition and two held-out ones), both in their own folders."""
    import json
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    make = (repo / "Makefile").read_text()
    assert "demo --config_path configs/demo.json --alongside configs/demo_recovery.json" in make
    paper, recovery = (json.loads((repo / "configs" / f).read_text()) for f in ("demo.json", "demo_recovery.json"))
    assert paper["output_dir"] != recovery["output_dir"]
    cfg = StudyConfig(**recovery)
    assert cfg.task_preset == "full" and cfg.train_seeds == [1000]
    assert cfg.methods == ["expert", "lookup_table", "recovering"]
    names = [s.name for s in cfg.suites]
    assert names[0] == "nominal" and {"train_drop", "heldout_far_drop", "heldout_latency_2"} == set(names[1:])
    held_out = {s for a in HELD_OUT_AXES for s in a.held_out}
    assert set(names[1:]) & held_out == {"heldout_far_drop", "heldout_latency_2"}


def test_make_study_runs_both_tasks_with_every_method_and_three_seeds():
    """make study: the paper-task study and the held-out protocol on the full task in one pool, each in its own
    folder."""
    import json
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    make = (repo / "Makefile").read_text()
    assert "report --config_path configs/report_full.json --alongside configs/report_heldout.json" in make
    paper, heldout = (
        json.loads((repo / "configs" / f).read_text()) for f in ("report_full.json", "report_heldout.json")
    )
    assert paper["output_dir"] != heldout["output_dir"]
    paper, heldout = StudyConfig(**paper), StudyConfig(**heldout)
    assert (paper.task_preset, heldout.task_preset) == ("paper", "full")
    assert len(paper.train_seeds) == len(heldout.train_seeds) == 3
    assert {"recovering", "act", "lookup_table", "expert"} <= set(heldout.methods)
    assert {s.name for s in heldout.suites} >= {s for a in HELD_OUT_AXES for s in a.held_out}


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"methods": ["clocked_lstm", "recovering"]}, "'clocked_lstm': the clocked planner trains on exactly 10-frame"),
        ({"methods": ["recovering_dagger"]}, "'recovering_dagger': the study's DAgger round is set up for the paper"),
        ({"data_efficiency": [10]}, "'clocked_lstm' (data_efficiency): the clocked planner"),
        ({"task_preset": "bogus"}, "task_preset must be one of ['full', 'paper'], got 'bogus'"),
    ],
)
def test_a_method_that_cannot_train_on_the_task_is_refused_up_front(changes, message, tmp_path):
    with pytest.raises(ConfigError) as err:
        StudyConfig(**{"output_dir": str(tmp_path / "never"), "preset": "heldout", **changes})
    assert message in str(err.value) and "\n" not in str(err.value)
    assert not (tmp_path / "never").exists()


@pytest.mark.slow
def test_a_tiny_heldout_study_reports_the_axis_table_and_cross_checks_on_the_full_task(tmp_path):
    out = tmp_path / "study"
    latency = ("train_latency", "heldout_latency_2", "heldout_latency_jitter")  # the latency axis, complete
    cfg = StudyConfig(
        output_dir=str(out),
        preset="heldout",
        num_episodes=20,
        epochs=2,
        train_seeds=[1000],
        workers=1,
        methods=["lookup_table", "recovering"],
        suites=[SuiteSpec("nominal", 2), *(SuiteSpec(s, 2) for s in latency)],
        cli_check_episodes=2,
    )
    from lerobot_pnp.integration.recorded_task import read_recorded
    from lerobot_pnp.report.run import run_study

    run_study(cfg)
    assert read_recorded(out / "dataset")["preset"] == "full"  # the task every suite applies its changes to
    ckpt = out / "train/recovering/seed1000/checkpoints/last/pretrained_model"
    assert read_recorded(ckpt)["preset"] == "full"  # what `lerobot-eval --policy.path` evaluates on
    assert json.loads((ckpt / "config.json").read_text())["max_episode_length"] == 41  # the full task's episodes
    summary = json.loads((out / "summary.json").read_text())
    assert summary["lerobot_eval_cli_check"]["agree"] == 2
    axes = summary["held_out_axes"]
    assert [(a["axis"], a["method"]) for a in axes] == [("latency", "lookup_table"), ("latency", "recovering")]
    assert all(set(a["held_out_suites"]) == set(latency[1:]) for a in axes)
    # the lookup table runs 2 per suite; the recovering planner, the preset's claims' method, goes on to 2x n
    # (no interval over 2 or 4 episodes is +-4.5 pts wide)
    assert [a["held_out"]["n"] for a in axes] == [4, 8]
    report = (out / "report.md").read_text()
    section = report[report.index("### latency: how old the observations are") :]
    assert "| lookup table |" in section and "| recovering LSTM |" in section
    assert "### timing" not in report  # an axis whose suites were not evaluated has no table
    assert "- *Recovery generalises along latency*" in report


def test_the_recovering_planners_train_with_the_recipes_batch(tmp_path):
    """The recovering planners train in the study as the recipe (and DAgger) does, 32 episodes per batch: the
    study's default of 64 halves the optimiser steps, which measurably weakens them (heldout_protocol.md). The
    batch is part of their training key; the clocked planners keep the default and their keys."""
    from lerobot_pnp.dagger import RECOVERING_BATCH_SIZE, DaggerConfig

    assert RECOVERING_BATCH_SIZE == DaggerConfig.batch_size == 32
    ctx = methods.TrainContext(tmp_path, tmp_path / "train", 1000, 2, data_keys={"keyframe": "k"})
    for name in ("recovering", "memoryless_mlp", "phase_told_mlp", "recovering_dagger"):
        (m,) = methods.get_methods([name])
        assert m.batch_size == 32 and methods.train_stage(m, ctx).parts["batch_size"] == 32
    (clocked,) = methods.get_methods(["clocked_lstm"])
    assert clocked.batch_size is None and "batch_size" not in methods.train_stage(clocked, ctx).parts


def test_the_report_notes_only_what_applies_to_the_study():
    from lerobot_pnp.report.markdown import _notes

    paper = "\n".join(_notes([], ["nominal", "edge_strip", "grasp_miss"], "paper"))
    assert "inside strip" in paper and "20-keyframe budget" in paper and "spare attempts" not in paper
    full = "\n".join(_notes([], ["nominal", "train_drop", "heldout_far_drop"], "full"))
    assert "inside strip" not in full and "20-keyframe" not in full and "spare attempts" in full


def test_the_paper_study_trains_the_recipe_with_its_changes(tmp_path, monkeypatch):
    """``recipe_changes`` (the paper study: one LSTM layer) reaches every method that takes the recovering recipe,
    DAgger's round included, changes their training keys, and leaves the clocked planners, a method's own
    deviations from the recipe, and the held-out study (the shipped recipe) as they were."""
    from pathlib import Path

    from lerobot_pnp import dagger
    from lerobot_pnp.report import preamble, training
    from lerobot_pnp.report.job import train_context
    from lerobot_pnp.report.layout import StudyLayout
    from lerobot_pnp.report.schedule import Job

    paper, heldout = StudyConfig(preset="full"), StudyConfig(preset="heldout")
    assert paper.recipe_changes == {"num_layers": 1} and heldout.recipe_changes == {}
    ctx = train_context(Job("recovering", "1000", None), methods.METHODS["recovering"], paper, StudyLayout(tmp_path),
                   {"keyframe": tmp_path}, {"keyframe": "k"})  # fmt: skip
    assert ctx.recipe_changes == {"num_layers": 1}
    shipped = replace(ctx, recipe_changes={})
    for name in ("recovering", "memoryless_mlp", "phase_told_mlp", "recovering_dagger"):
        m = methods.METHODS[name]
        assert methods.policy_settings(m.policy_overrides, ctx)["num_layers"] == 1
        assert methods.policy_settings(m.policy_overrides, shipped)["num_layers"] == 2
        assert methods.train_stage(m, ctx).key != methods.train_stage(m, shipped).key
    clocked = methods.METHODS["clocked_lstm"]
    assert methods.train_stage(clocked, ctx).key == methods.train_stage(clocked, shipped).key
    augmenting = replace(ctx, recipe_changes={"latency_augment_prob": 0.2})  # the told MLP trains without it
    assert methods.policy_settings(methods.PHASE_TOLD_MLP, augmenting)["latency_augment_prob"] == 0.0
    assert methods.policy_settings(methods.RECOVERING_STUDY_SETTINGS, augmenting)["latency_augment_prob"] == 0.2

    seen, round0 = {}, tmp_path / "round0"
    round0.mkdir()
    (round0 / "config.json").write_text("{}")  # the DAgger config checks it is a checkpoint folder
    monkeypatch.setattr(training, "keyed_train", lambda m, c, method_of: (round0, False))
    monkeypatch.setattr(dagger, "run_dagger", lambda cfg: seen.setdefault("cfg", cfg) and {"final_checkpoint": "x"})
    dagger_method = methods.METHODS["recovering_dagger"]
    assert dagger_method.train(replace(ctx, train_dir=tmp_path / "recovering_dagger" / "1000")) == Path("x")
    assert seen["cfg"].policy.num_layers == 1

    lines = preamble._recipe_changes_line(paper, methods.get_methods(["clocked_lstm", "recovering"]))
    assert "`num_layers` = 1" in lines[0] and "recovering LSTM" in lines[0]
    assert preamble._recipe_changes_line(heldout, methods.get_methods(["recovering"])) == []
    # an unknown or fixed field, or a value the planner refuses, fails when the study is configured
    refused = (({"num_layerz": 1}, "num_layerz"), ({"mode": "clocked"}, "mode"), ({"hidden_size": -5}, "hidden_size"))
    for bad, named in refused:
        with pytest.raises(ConfigError, match=named):
            StudyConfig(preset="full", recipe_changes=bad)
