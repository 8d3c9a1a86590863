"""Episode counts chosen from the interval widths (``config.EpisodeRule``): where an evaluation stops,
its key, and that reusing a fixed-n record by truncation gives exactly the episodes a fresh run makes."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import pytest

from lerobot_pnp import cli
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.stats import wilson_interval
from lerobot_pnp.integration.recorded_task import read_recorded
from lerobot_pnp.report import methods
from lerobot_pnp.report.config import EpisodeRule, StudyConfig, SuiteSpec
from lerobot_pnp.report.job import run_job
from lerobot_pnp.report.layout import StudyLayout
from lerobot_pnp.report.schedule import Job
from lerobot_pnp.report.stages import dataset_stage, eval_stage
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

RULE = EpisodeRule(half_width=0.1, block=50, fixed_methods=())


def test_a_claim_methods_cell_runs_n_then_goes_on_only_while_its_interval_is_wide():
    rule = EpisodeRule(half_width=0.17, block=50, fixed_methods=("expert",), claim_methods=("recovering",))
    assert rule.for_method("expert") is None and rule.for_method("act") is rule
    extended = rule.for_method("recovering")
    assert extended.stops(100, 50) == [100, 150, 200] and extended.stops(130, 50) == [130, 180, 230, 260]
    assert extended.stop_at([True] * 100, 100, 50) == 100  # 100/100: [96.3, 100] %, decided at n
    ninety = ([True] * 9 + [False]) * 20
    assert extended.stop_at(ninety[:100], 100, 50) is None  # 90/100: +-5.9 pts, wider than 4.5: go on
    assert extended.stop_at(ninety[:150], 100, 50) is None  # 135/150: +-4.9 pts
    assert extended.stop_at(ninety, 100, 50) == 200  # 180/200: +-4.2 pts, or the most (2x n) in any case
    assert extended.stop_at([False] * 200, 100, 50) == 100  # 0/100 is decided too: the rule reads width only
    assert extended.key() == {"half_width": 0.045, "block": 50, "from_n": True, "max_factor": 2}


def test_a_claim_method_extends_the_fixed_runs_episodes_with_the_next_seeds(tmp_path):
    """A claim method's evaluation is the fixed run's n episodes, then the seeds after them while undecided."""
    layout = StudyLayout(tmp_path / "s")
    study = dict(output_dir=str(layout.out), preset="quick", num_episodes=10, workers=1, methods=["lookup_table"],
                 suites=[SuiteSpec("nominal", 4)], eval_batch_size=2, cli_check_episodes=0)  # fmt: skip
    records, *_ = _job(StudyConfig(**study, episodes_rule=None), layout)
    fixed = [vars(r) for r in records["nominal"]]
    never = {"block": 2, "fixed_methods": [], "claim_methods": ["lookup_table"], "claim_half_width": 1e-6}
    records, *_ = _job(StudyConfig(**study, episodes_rule=never), layout)  # never decided: 2 x n
    extended = [vars(r) for r in records["nominal"]]
    assert [e["seed"] for e in extended] == list(range(100_000, 100_008)) and extended[:4] == fixed
    stored = json.loads(layout.eval_record("lookup_table", "-", "nominal").read_text())
    assert stored["parts"]["episodes_rule"] == {"half_width": 1e-6, "block": 2, "from_n": True, "max_factor": 2}
    at_once = {**never, "claim_half_width": 0.49}  # decided at n: the fixed run's episodes exactly
    records, *_ = _job(StudyConfig(**study, episodes_rule=at_once), layout)
    assert [vars(r) for r in records["nominal"]] == fixed


def test_a_cell_near_0_stops_after_one_block_and_one_near_half_goes_on():
    assert RULE.stops(200, 50) == [50, 100, 150, 200]
    assert RULE.stops(130, 50) == [50, 130]  # 100 would leave 30 episodes, less than a batch: skipped
    assert RULE.stops(30, 50) == [30]
    assert RULE.stop_at([False] * 50, 200, 50) == 50  # 0/50: [0, 7.1] %, +-3.6 pts
    half = [True, False] * 25
    assert RULE.stop_at(half, 200, 50) is None  # 25/50: [36.6, 63.4] %, +-13.4 pts: needs the next block
    assert RULE.stop_at(half * 2, 200, 50) == 100  # 50/100: +-9.6 pts
    assert RULE.stop_at(half * 4, 120, 50) == 120  # never decided before n: n
    lo, hi = wilson_interval(25, 50)
    assert not RULE.decided(25, 50) and (hi - lo) / 2 > RULE.half_width


@pytest.mark.parametrize(
    ("rule", "message"),
    [
        ({"half_width": 0.0}, "episodes_rule.half_width must be in (0, 0.5) (a fraction), got 0.0"),
        ({"half_width": 10}, "got 10"),
        ({"block": 30}, "episodes_rule.block must be a positive multiple of eval_batch_size (50), got 30"),
        ({"fixed_methods": ["expert", "bogus"]}, "episodes_rule.fixed_methods: unknown method(s) ['bogus']; valid:"),
        (
            {"halfwidth": 0.1},
            "episodes_rule: unknown field(s) ['halfwidth']; valid: ['block', 'claim_half_width', 'claim_max_factor',",
        ),
        ({"claim_methods": ["bogus"]}, "episodes_rule.claim_methods: unknown method(s) ['bogus']; valid:"),
        (
            {"fixed_methods": ["expert"], "claim_methods": ["expert"]},
            "episodes_rule: ['expert'] both in fixed_methods and claim_methods; name each in one",
        ),
        ({"claim_max_factor": 0}, "episodes_rule.claim_max_factor must be an integer >= 1, got 0"),
        ({"claim_half_width": 0.6}, "episodes_rule.claim_half_width must be in (0, 0.5) (a fraction), got 0.6"),
    ],
)
def test_a_bad_rule_is_a_config_error_naming_the_value(rule, message):
    with pytest.raises(ConfigError) as err:
        StudyConfig(preset="quick", episodes_rule=rule)
    assert message in str(err.value)


def test_the_command_line_takes_a_rule_and_refuses_a_bad_one_in_one_line(capsys, tmp_path):
    assert cli.main(["report", "--episodes_rule.block=30", f"--output_dir={tmp_path / 'never'}"]) == 2
    err = capsys.readouterr().err.strip()
    assert "episodes_rule.block must be a positive multiple" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "never").exists()
    heldout = StudyConfig(preset="heldout").episodes_rule  # the expert under the rule, the planner extended
    assert heldout.fixed_methods == () and heldout.claim_methods == ("recovering",)
    assert StudyConfig(preset="heldout", fixed_episodes=True).episodes_rule is None  # off
    full = StudyConfig(preset="full").episodes_rule  # the paired comparisons' methods run n, the others +-10 pts
    assert full.fixed_methods == ("expert", "lookup_table", "clocked_lstm") and full.half_width == 0.1
    assert StudyConfig(preset="demo").episodes_rule is None


def test_the_rule_is_a_key_part_of_an_adaptive_evaluation_only(tmp_path):
    (lookup,) = methods.get_methods(["lookup_table"])
    ctx = methods.TrainContext(tmp_path, tmp_path / "train", 1000, 1, data_keys={"keyframe": "k"})
    cfg = StudyConfig(preset="quick")
    parts = [BaxterPnPEnvConfig(preset="paper").to_dict()]
    fixed = eval_stage(tmp_path / "e.json", lookup, ctx, 200, parts, cfg)
    assert fixed.key == eval_stage(tmp_path / "e.json", lookup, ctx, 200, parts, cfg, None).key  # as before
    assert "episodes_rule" not in fixed.parts
    adaptive = eval_stage(tmp_path / "e.json", lookup, ctx, 200, parts, cfg, RULE)
    adaptive.commit(episodes=[])
    assert adaptive.done() and fixed.changes() == ["episodes_rule"]  # never reused as a fixed-n record
    other = eval_stage(tmp_path / "e.json", lookup, ctx, 200, parts, cfg, replace(RULE, half_width=0.05))
    assert other.changes() == ["episodes_rule"]  # another rule: re-run
    same = eval_stage(tmp_path / "e.json", lookup, ctx, 200, parts, cfg, replace(RULE, fixed_methods=("expert",)))
    assert same.done()  # which methods are fixed does not change what an adaptive evaluation produces


def _job(cfg: StudyConfig, layout: StudyLayout):
    """run_job of the lookup table on ``cfg`` (its dataset made or found first)."""
    _, key = dataset_stage(layout.out, "dataset", cfg)
    root = layout.dataset()
    base_env = BaxterPnPEnvConfig.from_dict(read_recorded(root) or {})
    return run_job(Job("lookup_table", "-", None), cfg, layout, {"keyframe": root}, base_env, {"keyframe": key})


def test_a_truncated_fixed_record_is_exactly_a_fresh_adaptive_evaluation(tmp_path, capsys):
    """6 episodes in batches of 2: the fixed run; a rule stopping after the first 2 or 4 reuses its first
    episodes, and a fresh run under that rule makes the same episodes, field by field."""
    layout = StudyLayout(tmp_path / "s")
    study = dict(output_dir=str(layout.out), preset="quick", num_episodes=10, workers=1, methods=["lookup_table"],
                 suites=[SuiteSpec("nominal", 6)], eval_batch_size=2, cli_check_episodes=0)  # fmt: skip
    records, _, left, *_ = _job(StudyConfig(**study), layout)
    full = [vars(r) for r in records["nominal"]]
    assert [e["seed"] for e in full] == list(range(100_000, 100_006)) and left == []
    record = layout.eval_record("lookup_table", "-", "nominal")
    lo, hi = wilson_interval(sum(e["success"] for e in full[:4]), 4)
    rule = {"half_width": (hi - lo) / 2 + 1e-9, "block": 2, "fixed_methods": []}  # decided by 4 of 6 at the latest
    adaptive = StudyConfig(**study, episodes_rule=rule, report_only=True)
    records, timings, left, *_ = _job(adaptive, layout)
    keep = len(records["nominal"])
    assert keep in (2, 4) and left == [] and "of its 6 episodes (episodes_rule)" in capsys.readouterr().out
    assert [vars(r) for r in records["nominal"]] == full[:keep]
    assert "episodes_rule" not in json.loads(record.read_text())["parts"]  # the fixed record is kept as it is
    shutil.move(record, tmp_path / "fixed.json")
    records, *_ = _job(replace(adaptive, report_only=False), layout)  # a fresh run under the rule
    assert [vars(r) for r in records["nominal"]] == full[:keep]
    stored = json.loads(record.read_text())
    assert stored["parts"]["episodes_rule"] == {"half_width": rule["half_width"], "block": 2}
    assert [e["seed"] for e in stored["episodes"]] == list(range(100_000, 100_000 + keep))
    _, _, left, *_ = _job(replace(adaptive, episodes_rule=replace(adaptive.episodes_rule, half_width=0.4)), layout)
    assert [x.changed for x in left] == [("episodes_rule",)]  # another rule: not reused
    _, _, left, *_ = _job(StudyConfig(**study, report_only=True), layout)
    assert [x.changed for x in left] == [("episodes_rule",)]  # nor as a fixed-n record


def test_a_method_stopped_early_is_compared_with_the_lookup_table_on_the_seeds_both_ran():
    from lerobot_pnp.evaluation.records import EpisodeRecord
    from lerobot_pnp.evaluation.results import compare

    def runs(outcomes):
        return [
            EpisodeRecord(100_000 + i, ok, "" if ok else "dropped", 0, "", 1, 0.5, 0.3) for i, ok in enumerate(outcomes)
        ]

    planner = [True] * 200  # fixed at n
    lookup = [False] * 50  # stopped after one block
    results = {"recovering": {"1000": {"nominal": runs(planner)}}, "lookup_table": {"-": {"nominal": runs(lookup)}}}
    (paired,) = compare(results, "recovering", "nominal")
    assert paired.n == 50 and paired.a_only == 50 and paired.b_only == 0 and paired.difference == 1.0


def test_the_report_states_the_rule_under_intervals_and_nothing_when_it_is_off():
    from lerobot_pnp.report.preamble import _episodes_rule_sentence

    text = _episodes_rule_sentence(StudyConfig(preset="heldout"))
    assert "every method's but the claims' method's evaluation runs blocks" in text
    assert "The claims' method (recovering LSTM) runs at least every suite's n" in text and "up to 2x n" in text
    assert "blocks of 50 seeds" in text and "+-17 pts" in text and "the common prefix" in text
    assert "split over a learned method's 3 training seeds" in text and "1.7x narrower" in text
    assert _episodes_rule_sentence(StudyConfig(preset="quick")) == ""


def test_a_split_suite_gives_each_seed_its_share_in_whole_batches_and_an_unseeded_method_all_of_it():
    from lerobot_pnp.report.job import suites_for

    heldout, full = StudyConfig(preset="heldout"), StudyConfig(preset="full")
    expert, recovering = methods.get_methods(["expert", "recovering"])
    assert {n for _, n in suites_for(heldout, None, recovering)} == {100}  # 200 / 3 -> 67 -> two batches of 50
    assert {n for _, n in suites_for(heldout, None, expert)} == {200}
    assert {n for _, n in suites_for(heldout, 30, recovering)} == {200}  # a data-efficiency run: not split
    off = [(s.name, n) for s, n in suites_for(full, None, recovering)]
    assert off == [(s.name, n) for s, n in suites_for(full, None)] and ("nominal", 300) in off  # off: n per seed
    assert StudyConfig(preset="heldout", train_seeds=[1, 2, 3, 4, 5]).seed_episodes(200) == 40  # one short batch
    assert StudyConfig(preset="heldout", split_over_seeds=False).seed_episodes(200) == 200
