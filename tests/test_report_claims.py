"""Every claim of ``report/claims.py``, rendered from hand-made episode records (no simulation): the verdict
it prints when it holds, when it does not, and nothing when its inputs were not evaluated."""

from __future__ import annotations

import pytest

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.records import EpisodeRecord
from lerobot_pnp.evaluation.results import build_comparisons, build_table, evaluated_suites
from lerobot_pnp.report import claims
from lerobot_pnp.report.methods import get_methods

SEED = 1000  # the training seed of the learned methods


def _records(successes: int, n: int = 100) -> list[EpisodeRecord]:
    """``n`` episodes on the eval seeds 100000.., the first ``successes`` of them successful."""
    return [
        EpisodeRecord(100_000 + i, i < successes, "" if i < successes else "dropped", 3, "", 10, 0.6, 0.0)
        for i in range(n)
    ]


def _render(name: str, rates: dict[tuple[str, str], int]) -> list[str]:
    """The lines of claim ``name`` from ``{(method, suite): successes out of 100}``."""
    results: dict = {}
    for (method, suite), k in rates.items():
        (m,) = get_methods([method])
        results.setdefault(method, {}).setdefault(str(SEED) if m.learned else "-", {})[suite] = _records(k)
    methods = get_methods(list(results))
    suites = evaluated_suites(results)
    (claim,) = [c for c in claims.CLAIMS if c.name == name]
    return claim.render(build_table(results, methods, suites), build_comparisons(results, methods, suites))


def test_generalisation():
    assert "-> holds." in _render("generalisation", {("clocked_lstm", "nominal"): 100})[0]
    assert "does not hold (below 90 %)" in _render("generalisation", {("clocked_lstm", "nominal"): 50})[0]
    assert _render("generalisation", {("clocked_lstm", "nudge_0.03"): 100}) == []


def test_learned_planner_needed():
    (line,) = _render("learned planner needed", {("clocked_lstm", "nominal"): 100, ("lookup_table", "nominal"): 50})
    assert "+50.0 pts" in line and line.endswith("-> holds.")
    (line,) = _render("learned planner needed", {("clocked_lstm", "nominal"): 90, ("lookup_table", "nominal"): 90})
    assert "not shown: the paper's task does not separate them." in line
    assert _render("learned planner needed", {("clocked_lstm", "nominal"): 90}) == []  # no baseline to pair with


def test_feedback_corrects_a_disturbance():
    lines = _render(
        "feedback corrects a disturbance",
        {
            ("clocked_lstm", "nudge_0.03"): 95,
            ("lookup_table", "nudge_0.03"): 40,
            ("clocked_lstm", "nudge_0.05"): 60,
            ("lookup_table", "nudge_0.05"): 60,
        },
    )
    assert len(lines) == 2  # obs_noise_0.005 was not evaluated: no line for it
    assert "`nudge_0.03`" in lines[0] and lines[0].endswith("holds: the benchmark discriminates here.")
    assert "`nudge_0.05`" in lines[1] and lines[1].endswith("not shown on this suite.")


def test_feedback_has_a_cost():
    rates = {("clocked_lstm", "latency"): 30, ("lookup_table", "latency"): 90}
    (line,) = _render(
        "feedback has a cost", {**rates, ("clocked_lstm", "nominal"): 90, ("lookup_table", "nominal"): 90}
    )
    assert "`latency` -60.0 pts" in line and "`nominal`" not in line
    assert _render("feedback has a cost", {("clocked_lstm", "latency"): 90, ("lookup_table", "latency"): 30}) == []


def test_unless_trained_for_it():
    rates = {("recovering", "latency"): 90, ("recovering", "random_yaw"): 80, ("lookup_table", "latency"): 70}
    assert _render("unless trained for it", rates) == []  # the lookup table was not run on random_yaw
    (line,) = _render("unless trained for it", {**rates, ("lookup_table", "random_yaw"): 20})
    assert "`latency` 90.0%" in line and "`random_yaw` 80.0%" in line and "(lookup table 70.0%" in line


def test_memory_matters_clocked():
    (line,) = _render("memory matters (clocked)", {("clocked_lstm", "nominal"): 95, ("memoryless", "nominal"): 20})
    assert "95.0% [" in line and "vs 20.0% [" in line
    assert _render("memory matters (clocked)", {("clocked_lstm", "nominal"): 95}) == []


BOTH = {("recovering", "nominal"): 95, ("memoryless_mlp", "nominal"): 45}


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        ({}, "-> memory matters beyond the intervals."),
        (
            {("memoryless_mlp", "nominal"): 93},
            "no difference beyond the intervals: memory is not shown to matter here.",
        ),
        ({("phase_told_mlp", "nominal"): 10}, "below the plain MLP, so being told the phase does not replace memory."),
        (
            {("phase_told_mlp", "nominal"): 90},
            ": 90 % of the gap closed, so the phase is most of what memory supplies.",
        ),
        ({("phase_told_mlp", "nominal"): 60}, ": 30 % of the gap closed, so memory supplies more than the phase."),
        (
            {("memoryless_mlp", "nominal"): 95, ("phase_told_mlp", "nominal"): 95},
            "Told the phase (privileged), the MLP",
        ),
    ],
)
def test_memory_tracks_the_phase(extra, expected):
    (line,) = _render("memory tracks the phase", {**BOTH, **extra})
    assert expected in line
    assert "suite `slack`" not in line  # slack not evaluated: its sentence is left out
    if ("phase_told_mlp", "nominal") not in extra:
        assert "Told the phase" not in line


@pytest.mark.parametrize(("told_slack", "slower"), [(95, True), (62, False)])
def test_memory_tracks_the_phase_with_the_slack_suite(told_slack, slower):
    slack = {("recovering", "slack"): 97, ("memoryless_mlp", "slack"): 50, ("phase_told_mlp", "slack"): told_slack}
    (line,) = _render("memory tracks the phase", {**BOTH, ("phase_told_mlp", "nominal"): 60, **slack})
    assert f"(suite `slack`) the told MLP reaches {told_slack}.0%" in line
    assert ("wastes steps where memory keeps time" in line) is slower
    assert _render("memory tracks the phase", {("recovering", "nominal"): 95}) == []  # no matched MLP


def test_planner_corrects_itself():
    lines = _render(
        "planner corrects itself",
        {("clocked_lstm", "grasp_miss"): 90, ("clocked_lstm", "drop"): 20, ("recovering", "displace"): 10},
    )
    assert len(lines) == 2  # recovering_dagger was not evaluated
    assert "(clocked LSTM)" in lines[0] and lines[0].endswith("holds on `grasp_miss` (95 % interval above 50 %).")
    assert "(recovering LSTM)" in lines[1] and lines[1].endswith("does not hold on any of them.")


def test_what_the_teacher_adds():
    (line,) = _render(
        "what the teacher adds",
        {
            ("recovering", "nominal"): 50,
            ("recovering_dagger", "nominal"): 95,
            ("recovering", "drop"): 90,
            ("recovering_dagger", "drop"): 30,
            ("recovering", "slack"): 80,
            ("recovering_dagger", "slack"): 82,
        },
    )
    assert "better on `nominal` 50.0%" in line and "worse on `drop` 90.0%" in line and "slack" not in line
    assert _render("what the teacher adds", {("recovering", "nominal"): 50}) == []


def test_what_dart_adds_and_dart_corrects_itself():
    rates = {("recovering", "drop"): 0, ("recovering_dart", "drop"): 85, ("recovering", "random_yaw"): 100}
    (line,) = _render("what DART adds", {**rates, ("recovering_dart", "random_yaw"): 25})
    assert line.startswith("- *What the teacher adds (DART, 1 round, 300 labelled episodes)*")
    assert "better on `drop` 0.0% [0.0, 3.7] -> 85.0%" in line and "worse on `random_yaw` 100.0%" in line
    lines = _render("planner corrects itself", rates)
    assert "(recovering LSTM + DART): `drop` 85.0%" in lines[-1] and lines[-1].endswith(
        "holds on `drop` (95 % interval above 50 %)."
    )


TESTED = {
    "generalisation",
    "learned planner needed",
    "feedback corrects a disturbance",
    "feedback has a cost",
    "unless trained for it",
    "memory matters (clocked)",
    "memory tracks the phase",
    "planner corrects itself",
    "what the teacher adds",
    "what DART adds",
    *(f"generalises along {a}" for a in ("timing", "magnitude", "count", "latency", "combination")),
}


def test_every_claim_has_a_test():
    assert {c.name for c in claims.CLAIMS} == TESTED


def test_a_claim_naming_an_unknown_method_or_suite_fails_the_check():
    bad = claims.Claim("typo", ("recovering_lstm",), ("nominal",), lambda table, comparisons: [])
    with pytest.raises(ConfigError, match="'recovering_lstm'.*valid:"):
        claims.check_claims((*claims.CLAIMS, bad))
    with pytest.raises(ConfigError, match="unknown suite 'nudge_3cm'"):
        claims.check_claims((claims.Claim("typo", ("recovering",), ("nudge_3cm",), lambda t, c: []),))
    claims.check_claims(claims.CLAIMS + (claims.Claim("group", ("recovering",), ("nudge",), lambda t, c: []),))


def test_the_quick_preset_renders_its_three_claims_in_order():
    """lookup_table and clocked_lstm on nominal and nudge_0.03 (the quick preset): the claims that render."""
    rates = {(m, s): k for (m, k) in (("clocked_lstm", 97), ("lookup_table", 60)) for s in ("nominal", "nudge_0.03")}
    results: dict = {}
    for (method, suite), k in rates.items():
        tag = str(SEED) if method == "clocked_lstm" else "-"
        results.setdefault(method, {}).setdefault(tag, {})[suite] = _records(k)
    methods = get_methods(["lookup_table", "clocked_lstm"])
    suites = evaluated_suites(results)
    lines = claims.render_claims(build_table(results, methods, suites), build_comparisons(results, methods, suites))
    assert [line.split("*")[1] for line in lines] == [
        "The LSTM planner generalises to unseen object positions",
        "A learned planner is needed for unseen positions",
        "Feedback at every step corrects a disturbed object",
    ]
    assert claims.render_claims({}, {}) == [
        "- (none: no claim has the methods and suites it reads among this study's evaluations)"
    ]


# --------------------------------------------------------------------------------------------- held-out axes
def _table(rates: dict[tuple[str, str], tuple[int, int]]):
    """The pooled table from ``{(method, suite): (successes, n)}``."""
    results: dict = {}
    for (method, suite), (k, n) in rates.items():
        (m,) = get_methods([method])
        results.setdefault(method, {}).setdefault(str(SEED) if m.learned else "-", {})[suite] = _records(k, n)
    methods = get_methods(list(results))
    return build_table(results, methods, evaluated_suites(results)), methods


LATENCY = {("recovering", "train_latency"): (99, 100)}


def test_held_out_axes_pool_each_side_and_need_every_suite():
    from lerobot_pnp.report import markdown

    rates = {
        ("recovering", "train_latency"): (90, 100),
        ("recovering", "heldout_latency_2"): (30, 100),
        ("recovering", "heldout_latency_jitter"): (50, 100),
        ("recovering", "train_mixture"): (80, 100),  # combination axis: its held-out suite was not run
    }
    table, methods = _table(rates)
    lines = markdown._held_out_section(table, methods)
    assert "### latency: how old the observations are" in lines and not any("### combination" in x for x in lines)
    (row,) = [line for line in lines if line.startswith("| recovering LSTM")]
    assert "| 90.0% [" in row and "n=100" in row
    assert "40.0% [" in row and "n=200" in row  # 80 of 200 over the two held-out suites
    assert "`heldout_latency_2` 30.0% [" in row and "`heldout_latency_jitter` 50.0% [" in row
    assert row.endswith("| -50.0 [-57.9, -39.8] | does not generalise |"), row
    assert "**Verdict rule**" in "\n".join(lines)
    partial = {k: v for k, v in rates.items() if k[1] != "heldout_latency_jitter"}  # one held-out suite missing
    assert markdown._held_out_section(*_table(partial)) == []


@pytest.mark.parametrize(
    ("held", "verdict", "text"),
    [
        ((97, 98), "generalises", "-> generalises (-1.5 points [-4.8, +3.2], margin 5)"),
        ((92, 93), "undecided", "-> undecided (-6.5 points [-11.1, -1.2], margin 5); about 1400 episodes a side"),
        ((80, 85), "does_not_generalise", "-> does not generalise (-16.5 points [-22.4, -10.1], margin 5)"),
    ],
)
def test_generalises_along_an_axis(held, verdict, text):
    from lerobot_pnp.evaluation.results import axis_result
    from lerobot_pnp.sim.suites import HELD_OUT_AXES

    rates = {**LATENCY, ("recovering", "heldout_latency_2"): (held[0], 100)}
    rates[("recovering", "heldout_latency_jitter")] = (held[1], 100)
    table, _ = _table(rates)
    (axis,) = [a for a in HELD_OUT_AXES if a.name == "latency"]
    assert axis_result(axis, "recovering", table).verdict == verdict
    (line,) = _render("generalises along latency", {k: v[0] for k, v in rates.items()})
    assert line.startswith("- *Recovery generalises along latency*") and text in line, line


def test_generalises_along_an_axis_names_the_other_methods_and_needs_the_recovering_planner():
    rates = {
        ("recovering", "train_mixture"): 99,
        ("recovering", "heldout_all_at_once"): 98,
        ("memoryless_mlp", "train_mixture"): 95,
        ("memoryless_mlp", "heldout_all_at_once"): 40,
        ("lookup_table", "train_mixture"): 30,
        ("lookup_table", "heldout_all_at_once"): 10,
        ("expert", "train_mixture"): 100,  # its held-out suite was not run: no verdict for it
    }
    first, others = _render("generalises along combination", rates)
    assert "recovering LSTM 98.0% [" in first and "-> undecided (-1.0 points [-6.1, +3.7], margin 5)" in first
    assert others.startswith("  Others on this axis: memoryless MLP (matched) 40.0% [")
    assert "40.0% [30.9, 49.8] held out -> does not generalise (-55.0 points" in others
    assert "lookup table 10.0% [" in others and "no verdict (below 90 % in distribution); -20.0 points" in others
    assert "expert" not in others
    no_recovering = {k: v for k, v in rates.items() if k[0] != "recovering"}
    assert _render("generalises along combination", no_recovering) == []


def test_the_held_out_test_is_one_sided_and_exact():
    from lerobot_pnp.evaluation.stats import Rate, below_p

    assert below_p(Rate(99, 100), Rate(98, 100)) == pytest.approx(0.5)  # Fisher: tables [[99, 1], [98, 2]]
    assert below_p(Rate(600, 600), Rate(558, 600)) < 1e-9
    assert below_p(Rate(50, 100), Rate(100, 100)) == 1.0  # above, not below
    assert below_p(Rate(0, 3), Rate(0, 3)) == 1.0
