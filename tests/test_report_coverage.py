"""What a report covers: ``--report_only`` names every evaluation it left out and why (and deletes
nothing), and suites of the same effective conditions are one evaluation that the report lists under both names."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lerobot_pnp import cli
from lerobot_pnp.cache import Stage
from lerobot_pnp.report import coverage, methods
from lerobot_pnp.report.config import StudyConfig
from lerobot_pnp.report.job import suites_for
from lerobot_pnp.report.stages import eval_stage
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.suites import get_suites


def test_suites_of_the_same_conditions_on_the_task_are_aliases():
    """``quiet`` switches off what the paper task has off anyway: on paper it is ``nominal``; on ``full`` it is not.
    The heldout preset's training-condition suites that ``full`` already draws repeat ``nominal``."""
    pairs = [(s, 4) for s in get_suites(["nominal", "quiet", "latency"])]
    paper, full = BaxterPnPEnvConfig(preset="paper"), BaxterPnPEnvConfig(preset="full")
    assert coverage.suite_aliases(pairs, paper) == {"nominal": "nominal", "quiet": "nominal", "latency": "latency"}
    assert set(coverage.suite_aliases(pairs, full).values()) == {"nominal", "quiet", "latency"}
    other_n = [(get_suites(["nominal"])[0], 4), (get_suites(["quiet"])[0], 5)]  # other episodes: other evaluations
    assert coverage.suite_aliases(other_n, paper) == {"nominal": "nominal", "quiet": "quiet"}
    heldout = StudyConfig(preset="heldout")
    aliases = coverage.suite_aliases(suites_for(heldout, None), full)
    assert {a: of for a, of in aliases.items() if a != of} == {"train_nudge": "nominal", "train_mixture": "nominal"}


def test_on_full_train_nudge_and_train_mixture_play_nominals_episodes(tmp_path):
    """Why the held-out study evaluates them as ``nominal``: each sets what the ``full`` task already sets (its
    nudge size; its three disturbances at the full preset's probabilities), so their env configs equal nominal's,
    and every seed plays the same episode, disturbances included: the expert's records on the same seeds are the
    same, field by field."""
    full = BaxterPnPEnvConfig(preset="full")
    configs = {s.name: s.env_configs(full) for s in get_suites(["nominal", "train_nudge", "train_mixture"])}
    assert all(len(c) == 1 and c[0].to_dict() == configs["nominal"][0].to_dict() for c in configs.values())
    (expert,) = methods.get_methods(["expert"])
    ctx = methods.TrainContext(tmp_path, tmp_path / "train", 1000, 1)
    runs = {name: [vars(r) for r in expert.evaluate(None, ctx, c[0], 6, 100_000, 6)] for name, c in configs.items()}
    assert runs["train_nudge"] == runs["nominal"] == runs["train_mixture"]
    assert any(r["perturbations"] for r in runs["nominal"])  # disturbances fired, the same in each


def test_an_evaluation_is_keyed_by_its_conditions_and_an_older_record_with_the_suite_name_stays_valid(tmp_path):
    (lookup,) = methods.get_methods(["lookup_table"])
    ctx = methods.TrainContext(tmp_path, tmp_path / "train", 1000, 1, data_keys={"keyframe": "k"})
    cfg = StudyConfig(preset="quick")
    parts = [BaxterPnPEnvConfig(preset="paper").to_dict()]
    a, b = (eval_stage(tmp_path / f"{n}.json", lookup, ctx, 4, parts, cfg) for n in ("nominal", "quiet"))
    assert a.key == b.key and "suite" not in a.parts
    old = tmp_path / "old.json"  # a record written when the suite's name was part of the key
    old.write_text(json.dumps({"key": "before", "parts": {**a.parts, "suite": "nominal"}}))
    assert eval_stage(old, lookup, ctx, 4, parts, cfg).done()
    assert not eval_stage(old, lookup, ctx, 5, parts, cfg).done()  # another part still counts


def test_a_cell_that_lost_a_seed_is_withheld_and_marked(tmp_path):
    results = {"m": {"1": {"nominal": ["r1"], "drop": ["d1"]}, "2": {"drop": ["d2"]}}, "e": {"-": {"nominal": ["x"]}}}
    stale = coverage.LeftOut("m", "2", "nominal", "stale", ("train.batch_size",))
    kept, left = coverage.withhold(results, [stale])
    assert kept == {"m": {"1": {"drop": ["d1"]}, "2": {"drop": ["d2"]}}, "e": {"-": {"nominal": ["x"]}}}
    assert [(x.tag, x.reason) for x in left] == [("1", "withheld"), ("2", "stale")]
    assert coverage.marks(left) == {("nominal", "m"): "**stale** (seed 2)"}
    assert "train.batch_size" in stale.why() and stale.to_json()["changed"] == ["train.batch_size"]
    labels = {"m": "method M"}
    assert (
        coverage.figure_note(left, ("nominal", "drop"), labels)
        == " (not drawn, left out of this report: method M on `nominal`)"
    )
    assert coverage.figure_note(left, ("drop",), labels) == ""
    missing = coverage.left_out("m", "1", "drop", Stage(tmp_path / "none.json", {"a": 1}), None)
    assert (missing.reason, missing.changed) == ("missing", ())


# ----------------------------------------------------------------------------------------------- end to end
STUDY = ["--preset", "quick", "--num_episodes", "10", "--workers", "1", "--train_seeds", "[1000]",
         "--methods", "[lookup_table,clocked_lstm]", "--cli_check_episodes", "0",
         "--suites", "[{name: nominal, n_episodes: 2}, {name: quiet, n_episodes: 2}]"]  # fmt: skip


def _study(out: Path, *flags: str) -> int:
    return cli.main(["report", "--output_dir", str(out), *STUDY, *flags])


def _files(root: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.mark.slow
def test_report_only_names_the_stale_evaluations_keeps_their_files_and_aliases_are_one_evaluation(tmp_path):
    out = tmp_path / "s"
    assert _study(out, "--epochs", "1") == 0
    for method, tag in (("lookup_table", "-"), ("clocked_lstm", "1000")):  # quiet = nominal on paper: evaluated once
        assert sorted(p.name for p in (out / f"evals/{method}/seed{tag}").iterdir()) == ["nominal.json"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["suite_aliases"] == {"quiet": "nominal"} and summary["left_out"] == []
    assert summary["success"]["quiet"] == summary["success"]["nominal"]
    report = (out / "report.md").read_text()
    assert "`quiet` = `nominal`" in report and "Left out of this report" not in report

    kept = {**_files(out / "evals"), **_files(out / "train")}
    assert _study(out, "--epochs", "2", "--report_only", "true") == 0  # the clocked LSTM's training key changed
    assert {**_files(out / "evals"), **_files(out / "train")} == kept  # nothing deleted, nothing rewritten
    summary = json.loads((out / "summary.json").read_text())
    left = {(x["method"], x["tag"], x["suite"]): x for x in summary["left_out"]}
    assert set(left) == {("clocked_lstm", "1000", "nominal"), ("clocked_lstm", "1000", "quiet")}
    assert all(x["reason"] == "stale" and x["changed"] == ["train.epochs"] for x in left.values())
    assert "clocked_lstm" not in summary["success"]["nominal"] and "lookup_table" in summary["success"]["nominal"]
    report = (out / "report.md").read_text()
    top = report[: report.index("## Methods")]
    assert "## Left out of this report" in top
    assert "| clocked LSTM (paper) | 1000 | `nominal` | stale: its key changed since it ran (train.epochs) |" in top
    row = next(line for line in report.splitlines() if line.startswith("| `nominal` |"))
    assert row.endswith("| **stale** (seed 1000) |"), row
    assert "not drawn, left out of this report: clocked LSTM (paper) on `nominal`" in report  # the heatmap's caption
    assert "training on disk, not the one this report's config states: train.epochs" in report  # the loss curves'

    dataset = _files(out / "dataset")
    assert _study(out, "--epochs", "1", "--num_episodes", "12", "--report_only", "true") == 0  # another dataset
    assert _files(out / "dataset") == dataset  # not regenerated: report_only makes nothing
    summary = json.loads((out / "summary.json").read_text())
    assert "stale (num_episodes): not generated (report_only)" in summary["generation"]["status"]
    left = {(x["method"], x["suite"]): x["changed"] for x in summary["left_out"]}
    assert left[("lookup_table", "nominal")] == ["data"] and left[("clocked_lstm", "nominal")] == ["data", "train.data"]
    assert "- Dataset `" in (out / "report.md").read_text()
