"""``lerobot-pnp compare`` over eval_info.json files: the study's own numbers for the same evaluations (pooled
training seeds, paired tests against the lookup table, the held-out verdict), and refusals in one line."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lerobot_pnp import cli
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation import results as study
from lerobot_pnp.evaluation.compare import CompareConfig, run_compare
from lerobot_pnp.evaluation.eval_info import read_eval_info
from lerobot_pnp.evaluation.records import EpisodeRecord
from lerobot_pnp.evaluation.stats import Rate, chi2_sf, paired_difference_interval, seed_agreement, wilson_interval
from lerobot_pnp.sim.suites import HELD_OUT_AXES

AXIS = next(a for a in HELD_OUT_AXES if a.name == "latency")
SUITES = ("nominal", *AXIS.in_distribution, *AXIS.held_out)
N, SEED = 40, 100_000
RATES = {"lookup_table": 0.5, "recovering": 0.98, "memoryless_mlp": 0.75}  # success probability per episode


def _study_results() -> dict:
    """method -> training seed -> suite -> records, as the study holds them (the lookup table trains nothing)."""
    rng = np.random.default_rng(0)
    tags = {"lookup_table": ["-"], "recovering": ["1000", "1001"], "memoryless_mlp": ["1000", "1001"]}
    return {
        m: {t: {s: [EpisodeRecord(SEED + i, bool(rng.random() < p), "", -1, "", 1, 0.0, 0.0) for i in range(N)]
                for s in SUITES} for t in tags[m]}
        for m, p in RATES.items()
    }  # fmt: skip


def eval_info(per_suite: dict[str, list[bool]]) -> dict:
    """A stock lerobot-eval eval_info.json: one task per suite (as --env.task writes it)."""
    per_task = [{"task_group": s, "task_id": 0, "metrics": {"sum_rewards": [float(x) for x in ok],
                 "max_rewards": [float(x) for x in ok], "successes": ok, "video_paths": []}}
                for s, ok in per_suite.items()]  # fmt: skip
    per_group = {s: {"pc_success": 100 * np.mean(ok), "n_episodes": len(ok)} for s, ok in per_suite.items()}
    return {"per_task": per_task, "per_group": per_group, "overall": {"n_episodes": sum(map(len, per_suite.values()))}}


def _write_runs(results: dict, root: Path) -> list[str]:
    specs = []
    for method, runs in results.items():
        paths = []
        for tag, suites in runs.items():
            path = root / method / tag
            path.mkdir(parents=True)
            outcomes = {s: [r.success for r in sorted(recs, key=lambda r: r.seed)] for s, recs in suites.items()}
            (path / "eval_info.json").write_text(json.dumps(eval_info(outcomes)))
            paths.append(str(path))
        specs.append(f"{method}={','.join(paths)}")
    return specs


def test_compare_reproduces_the_studys_pooled_rates_paired_tests_and_axis_verdict(tmp_path, capsys):
    results = _study_results()
    methods = [SimpleNamespace(name=m) for m in results]
    table = study.build_table(results, methods, SUITES)
    comparisons = study.build_comparisons(results, methods, SUITES)
    specs = _write_runs(results, tmp_path / "runs")
    assert cli.main(["compare", *specs, "--output_dir", str(tmp_path / "out"), "--alpha=0.05"]) == 0
    out = json.loads((tmp_path / "out" / "compare.json").read_text())
    assert (tmp_path / "out" / "compare.png").stat().st_size > 0
    assert (
        "## Held-out axes" in (tmp_path / "out" / "compare.md").read_text()
        and "## Pairs of runs" in capsys.readouterr().out
    )

    for s in SUITES:
        for m in results:
            assert out["success"][s][m] == json.loads(json.dumps(table[s][m].to_json()))
    pairs = {(p["run"], p["reference"], p["suite"]): p for p in out["pairs"]}
    for m in ("recovering", "memoryless_mlp"):
        for s in SUITES:
            ours, theirs = pairs[(m, "lookup_table", s)], comparisons[m][s]
            assert ours["study"] == json.loads(json.dumps(theirs.to_json()))
            assert ours["n"] == 2 * N and ours["verdict"] in ("improved", "held", "underpowered", "regressed")
    axes = {(a["axis"], a["method"]): a for a in out["held_out_axes"]}
    for m in results:
        assert axes[(AXIS.name, m)] == json.loads(json.dumps(study.axis_result(AXIS, m, table).to_json()))
    assert (
        axes[(AXIS.name, "recovering")]["verdict"] == "undecided"
    )  # -2.5 points [-6.8, +3.4]: too few episodes to decide
    two_methods = pairs[("memoryless_mlp", "recovering", "nominal")]  # two seeds each: paired seed by seed
    assert two_methods["n"] == 2 * N and len(two_methods["study"]["per_seed"]) == 2
    control = out["control"]["recovering"]["train_latency"]  # beside nominal on the same seeds and training seeds
    assert control["n"] == 2 * N and set(out["control"]["recovering"]) == set(SUITES) - {"nominal"}


def test_verdicts_and_the_paired_difference_interval():
    lo, hi = paired_difference_interval(both=50, a_only=20, b_only=2, neither=28)
    assert lo < 0.18 < hi and lo > 0  # a clear improvement: the interval excludes 0
    lo, hi = paired_difference_interval(both=95, a_only=0, b_only=0, neither=5)
    assert -0.05 < lo < 0 < hi < 0.05  # identical outcomes: a narrow interval around 0
    # paired episodes give a narrower interval than two independent samples of the same rates (Newcombe's hybrid)
    l1, u1 = wilson_interval(70, 100)
    l2, u2 = wilson_interval(52, 100)
    independent = 0.18 - np.hypot(0.7 - l1, u2 - 0.52), 0.18 + np.hypot(u1 - 0.7, 0.52 - l2)
    lo, hi = paired_difference_interval(both=50, a_only=20, b_only=2, neither=28)
    assert independent[0] < lo and hi < independent[1]


def _bad(tmp_path: Path, name: str, content) -> str:
    path = tmp_path / name
    path.mkdir(parents=True)
    (path / "eval_info.json").write_text(content if isinstance(content, str) else json.dumps(content))
    return str(path)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda t: [_bad(t, "a", "{not json")], "is not JSON"),
        (lambda t: [_bad(t, "a", {"results": [1, 2]})], "not a lerobot-eval eval_info.json"),
        (lambda t: [_bad(t, "a", {**eval_info({"nominal": [True]}), "per_group": {"nominal": {"n_episodes": 7}}})],
         "does not count"),
        (lambda t: [_bad(t, "a", eval_info({"nominal": [True] * 4})), _bad(t, "b", eval_info({"nominal": [True] * 5}))],
         "do not pair on ['nominal']"),
        (lambda t: [_bad(t, "a", eval_info({"nominal": [True]})), _bad(t, "b", eval_info({"drop": [True]}))],
         "share no suite"),
        (lambda t: [str(t / "missing")], "no eval_info.json at"),
        (lambda t: [f"x={_bad(t, 'a', eval_info({'nominal': [True]}))},{_bad(t, 'b', eval_info({'nominal': [0, 1]}))}"],
         "does not hold the suites and episode counts"),
    ],
)  # fmt: skip
def test_refusals_are_one_line_exit_2_and_write_nothing(tmp_path, capsys, make, message):
    runs = make(tmp_path)
    with pytest.raises(ConfigError) as err:
        run_compare(CompareConfig(runs=runs, output_dir=str(tmp_path / "out")))
    assert message in str(err.value) and "\n" not in str(err.value)
    assert cli.main(["compare", *runs, f"--output_dir={tmp_path / 'out'}"]) == 2
    assert message in capsys.readouterr().err and not (tmp_path / "out").exists()


def test_reads_another_benchmarks_eval_info(tmp_path):
    """LIBERO's layout: several tasks per suite, each from the same seeds; the tasks of a suite pool."""
    data = eval_info({"libero_spatial": [True, False]})
    data["per_task"].append({"task_group": "libero_spatial", "task_id": 1, "metrics": {"successes": [True, True]}})
    data["per_group"]["libero_spatial"]["n_episodes"] = 4
    path = _bad(tmp_path, "libero", data)
    assert read_eval_info(path).suites == {"libero_spatial": {0: [True, False], 1: [True, True]}}
    assert run_compare(CompareConfig(runs=[path])) == {"written": []}


def test_suites_pools_seeds_evaluated_on_different_sets_of_suites(tmp_path, capsys):
    """One seed evaluated on the whole protocol, another on a part of it: --suites compares the part they share,
    with the seeds pooled; a suite one of them lacks is refused in one line."""
    whole = _bad(tmp_path, "s1", eval_info({"nominal": [True, False], "drop": [False, False], "far": [True, True]}))
    part = _bad(tmp_path, "s2", eval_info({"nominal": [True, True], "drop": [True, False]}))
    result = run_compare(CompareConfig(runs=[f"x={whole},{part}"], suites="nominal,drop"))
    assert result == {"written": []}
    out = capsys.readouterr().out
    assert "| nominal | 4 | 75.0%" in out and "| drop | 4 | 25.0%" in out and "| far |" not in out
    with pytest.raises(ConfigError, match=r"holds no suite 'far'; it holds \['drop', 'nominal'\]"):
        run_compare(CompareConfig(runs=[f"x={whole},{part}"], suites="nominal,far"))


@pytest.mark.parametrize(("x", "dof"), [(3.841459, 1), (5.991465, 2), (7.814728, 3), (9.487729, 4), (11.0705, 5)])
def test_chi2_sf_gives_the_tables_five_percent_points(x, dof):
    assert chi2_sf(x, dof) == pytest.approx(0.05, abs=2e-6)
    assert chi2_sf(0.0, dof) == 1.0 and chi2_sf(200.0, dof) < 1e-30


def test_seed_agreement_tells_seeds_that_differ_from_seeds_within_evaluation_noise(tmp_path):
    """Three seeds at 93, 95 and 69 % of 200 episodes differ far beyond binomial noise; 85, 86 and 88 % do not.
    compare reports it per run of several seeds and suite, and a run of one path gets no test."""
    differ = seed_agreement([Rate(186, 200), Rate(190, 200), Rate(138, 200)])
    assert differ.dof == 2 and differ.chi2 == pytest.approx(68.19, abs=0.01) and differ.p_value < 1e-14
    assert differ.differ()
    same = seed_agreement([Rate(170, 200), Rate(172, 200), Rate(176, 200)])
    assert same.p_value > 0.5 and not same.differ()
    assert seed_agreement([Rate(10, 10), Rate(5, 5)]).p_value == 1.0
    with pytest.raises(ValueError, match="two or more training seeds"):
        seed_agreement([Rate(1, 2)])

    def seeds(name: str, wins: list[int]) -> str:
        paths = [_bad(tmp_path, f"{name}{k}", eval_info({"nominal": [i < w for i in range(200)]})) for k, w in
                 enumerate(wins)]  # fmt: skip
        return f"{name}={','.join(paths)}"

    single = _bad(tmp_path, "single", eval_info({"nominal": [True] * 200}))
    run_compare(CompareConfig(runs=[seeds("a", [186, 190, 138]), seeds("b", [170, 172, 176]), f"c={single}"],
                              output_dir=str(tmp_path / "out")))  # fmt: skip
    data = json.loads((tmp_path / "out" / "compare.json").read_text())
    assert set(data["seeds"]) == {"a", "b"}
    assert data["seeds"]["a"]["nominal"]["differ"] and not data["seeds"]["b"]["nominal"]["differ"]
    text = (tmp_path / "out" / "compare.md").read_text()
    assert "| a | nominal | 93.0%, 95.0%, 69.0% | 68.2 (2) |" in text and "| b | nominal |" in text


def _expert_info(per_suite: dict[str, list[bool]], seed: int) -> dict:
    """``lerobot-pnp expert``'s eval_info.json: the stock layout plus each episode's seed."""
    data = eval_info(per_suite)
    for task in data["per_task"]:
        task["metrics"]["seeds"] = list(range(seed, seed + len(task["metrics"]["successes"])))
    return data


def _written(out: Path) -> dict[str, bytes]:
    return {
        name: (out / name).read_bytes()
        for name in ("compare.md", "compare.json", "compare.png")
        if (out / name).exists()
    }


OUTCOMES = {"nominal": [True, False, True, True], "drop": [False, False, True, True]}


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda t: [_bad(t, "a", _expert_info(OUTCOMES, 0)), _bad(t, "b", _expert_info(OUTCOMES, 5000))],
         "were evaluated on other seeds (suite 'nominal' task 0, episode 0: seed 0 vs 5000)"),
        (lambda t: [f"x={_bad(t, 'a', _expert_info(OUTCOMES, 0))},{_bad(t, 'b', _expert_info(OUTCOMES, 7))}"],
         "were evaluated on other seeds"),
        (lambda t: [_bad(t, "a", {**eval_info(OUTCOMES), "per_group": [1, 2]})], "per_group is a list"),
        (lambda t: [_bad(t, "a", {**eval_info(OUTCOMES), "per_group": "nominal"})], "per_group is a str"),
        (lambda t: [_bad(t, "a", {"per_task": [*eval_info(OUTCOMES)["per_task"],
                                               {"task_group": "far", "task_id": 3, "metrics": {"successes": [True]}}]})],
         "suite 'far' of run 'a' shares no task id with the control 'nominal'"),
        (lambda t: [_bad(t, "a", {"per_task": [{"task_group": "x", "task_id": 0, "metrics": {"successes": [[1], 2]}}]})],
         "non-boolean"),
        (lambda t: [_bad(t, "a", {**_expert_info(OUTCOMES, 0), "per_group": None} | {"per_task": [
            {"task_group": "x", "task_id": 0, "metrics": {"successes": [True], "seeds": ["0"]}}]})],
         "seeds is not one integer per episode"),
    ],
)  # fmt: skip
def test_malformed_or_unpaired_runs_are_one_line_and_write_nothing(tmp_path, capsys, make, message):
    runs = make(tmp_path)
    with pytest.raises(ConfigError) as err:
        run_compare(CompareConfig(runs=runs, output_dir=str(tmp_path / "out")))
    assert message in str(err.value) and "\n" not in str(err.value), str(err.value)
    assert cli.main(["compare", *runs, f"--output_dir={tmp_path / 'out'}"]) == 2
    assert message in capsys.readouterr().err and not (tmp_path / "out").exists()


def test_recorded_seeds_are_checked_and_the_page_says_how_episodes_paired(tmp_path, capsys):
    a, b = _bad(tmp_path, "a", _expert_info(OUTCOMES, 9)), _bad(tmp_path, "b", _expert_info(OUTCOMES, 9))
    stock = _bad(tmp_path, "stock", eval_info(OUTCOMES))
    run_compare(CompareConfig(runs=[a, b]))
    assert "Every run records its episodes' seeds: they are the same in every run" in capsys.readouterr().out
    run_compare(CompareConfig(runs=[a, b, stock]))
    out = capsys.readouterr().out
    assert "`a`, `b` record(s) the episodes' seeds, `stock` not" in out and "pair by index" in out
    run_compare(CompareConfig(runs=[stock]))
    assert "(eval_info.json does not record it)" in capsys.readouterr().out


def test_a_control_that_is_not_a_suite_is_refused_naming_the_suites(tmp_path, capsys):
    run = _bad(tmp_path, "a", eval_info(OUTCOMES))
    assert cli.main(["compare", run, "--control", "nominl", "--output_dir", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--control 'nominl' is not a suite of the runs compared; valid: ['drop', 'nominal']" in err
    assert "\n" not in err and not (tmp_path / "out").exists()
    assert cli.main(["compare", run, "--control", "drop", "--output_dir", str(tmp_path / "out")]) == 0
    assert "## Each suite beside the control `drop`" in (tmp_path / "out" / "compare.md").read_text()
    libero = _bad(tmp_path, "libero", eval_info({"libero_spatial": [True, False]}))  # no nominal: no control arm
    assert run_compare(CompareConfig(runs=[libero])) == {"written": []}


def test_an_input_over_the_size_limit_is_refused_before_it_is_read(tmp_path):
    from lerobot_pnp.evaluation.eval_info import MAX_INPUT_BYTES

    path = Path(_bad(tmp_path, "big", eval_info(OUTCOMES))) / "eval_info.json"
    os.truncate(path, MAX_INPUT_BYTES + 1)  # a sparse file: nothing of it is stored, or read
    with pytest.raises(ConfigError, match=rf"holds {MAX_INPUT_BYTES + 1:,} bytes, over the {MAX_INPUT_BYTES:,}"):
        run_compare(CompareConfig(runs=[str(path.parent)]))


def test_the_three_outputs_are_one_set(tmp_path, monkeypatch, capsys):
    """A figure that cannot be drawn changes nothing; a crash while the set is written leaves the previous set."""
    from lerobot_pnp import outputs
    from lerobot_pnp.evaluation import plots

    out = tmp_path / "out"
    first = [_bad(tmp_path, "a", eval_info(OUTCOMES))]
    assert cli.main(["compare", *first, "--output_dir", str(out)]) == 0
    before = _written(out)
    assert set(before) == {"compare.md", "compare.json", "compare.png"}
    second = [_bad(tmp_path, "b", eval_info({"nominal": [True] * 4}))]

    def broken_figure(*args, **kwargs):
        raise ValueError("Unknown symbol: \\frac")

    monkeypatch.setattr(plots, "rate_bars", broken_figure)
    assert cli.main(["compare", *second, "--output_dir", str(out)]) == 2
    assert "compare.png cannot be drawn" in capsys.readouterr().err and _written(out) == before
    monkeypatch.undo()
    real = outputs.write_bytes_atomic

    def crash_on_png(path, data):
        if path.name.startswith("compare.png"):
            raise OSError(28, "No space left on device")
        real(path, data)

    monkeypatch.setattr(outputs, "write_bytes_atomic", crash_on_png)
    assert cli.main(["compare", *second, "--output_dir", str(out)]) == 2
    assert _written(out) == before
    monkeypatch.undo()
    assert cli.main(["compare", *second, "--output_dir", str(out)]) == 0  # its own files: replaced
    assert _written(out)["compare.md"] != before["compare.md"] and not list(out.glob("*.pnp-new"))
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "compare.md").write_text("my notes")
    assert cli.main(["compare", *second, "--output_dir", str(tmp_path / "mine")]) == 2  # the user's: refused
    assert (tmp_path / "mine" / "compare.md").read_text() == "my notes"


@pytest.mark.parametrize("name", ["a$b", "$\\frac", "$x^{$"])
def test_names_are_drawn_as_written(tmp_path, name):
    run = _bad(tmp_path, "a", eval_info(OUTCOMES))
    assert cli.main(["compare", f"{name}={run}", "--output_dir", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "compare.png").stat().st_size > 0
    assert f"| suite | n | {name.replace(chr(92), chr(92) * 2)} |" in (tmp_path / "out" / "compare.md").read_text()


def test_paths_with_equals_and_commas(tmp_path, capsys):
    """A path holding '=' or ',' is one PATH when it exists; NAME=PATHS splits at the first '=' and keeps pieces
    joined by commas together where they name an existing path; errors name the whole argument."""
    lr = _bad(tmp_path, "sweep/lr=0.1", eval_info(OUTCOMES))
    ab = _bad(tmp_path, "sweep/a,b", eval_info(OUTCOMES))
    plain = _bad(tmp_path, "sweep/c", eval_info(OUTCOMES))
    assert cli.main(["compare", lr, f"pooled={ab},{plain},{lr}", "--output_dir", str(tmp_path / "out")]) == 0
    runs = json.loads((tmp_path / "out" / "compare.json").read_text())["runs"]
    assert runs == {"lr=0.1": [lr], "pooled": [ab, plain, lr]}
    missing = f"{tmp_path}/sweep/lr=0.2"
    assert cli.main(["compare", missing]) == 2
    assert f"run argument {missing!r}" in capsys.readouterr().err
    beside = f"{tmp_path}/sweep/c=9"  # sweep/c exists: the argument is one PATH, not NAME=PATH
    assert cli.main(["compare", beside]) == 2
    assert f"no eval_info.json at {beside!r} (its text before '=' is an existing path" in capsys.readouterr().err


def _cells(line: str) -> int:
    """The cells of a markdown table row: the pipes that are not backslash-escaped, less one."""
    return len(re.findall(r"(?<!\\)\|", line)) - 1


def test_user_text_is_escaped_wherever_it_reaches_markdown(tmp_path, capsys):
    hostile = "<script>alert(1)</script> a|b\nc"
    suite = "evil|suite\n| injected |"
    run = _bad(tmp_path, "a", eval_info({"nominal": [True, False], suite: [True, True]}))
    other = _bad(tmp_path, "b", eval_info({"nominal": [True, True], suite: [False, True]}))
    specs = [f"{hostile}={run},{other}", f"b`tick={other}"]
    assert cli.main(["compare", *specs, "--output_dir", str(tmp_path / "o")]) == 0
    page = (tmp_path / "o" / "compare.md").read_text()
    outside_code = re.sub(r"(`+).*?\1", "", page)  # a code span shows its text literally, tags included
    assert "<script>" not in outside_code and "&lt;script&gt;alert(1)&lt;/script&gt; a\\|b c" in page
    assert "- `<script>alert(1)</script> a|b c`: 2 run(s)" in page
    assert "evil\\|suite \\| injected \\|" in page and "``b`tick``" in page
    for table in re.findall(r"(?:^\|.*\n)+", page, re.M):
        rows = table.splitlines()
        assert all(_cells(r) == _cells(rows[0]) for r in rows), table
    assert "\n| injected |" not in page and "\nc=" not in page


def test_markdown_text_leaves_plain_names_alone_and_escapes_the_rest():
    from lerobot_pnp.support.markdown_text import code, text

    assert text("camera_planner-2.0 /x") == "camera_planner-2.0 /x" and code("a_b") == "`a_b`"
    assert text("a<b>&c|d\\e\r\nf\u2028g") == "a&lt;b&gt;&amp;c\\|d\\\\e f g"
    assert code("x`y") == "``x`y``" and code("`x") == "`` `x ``" and code("a|b", table=True) == "`a\\|b`"
    assert code("<b>\nc") == "`<b> c`"


def test_large_tails_agree_with_the_exact_sums(monkeypatch):
    """Beyond EXACT_TRIALS the tails are summed in floating point (linear cost): the same p as the exact sums."""
    from lerobot_pnp.evaluation import stats

    signs = [(4_800, 5_400), (5_100, 5_000), (10_000, 10_000), (3, 20_000)]
    fishers = [
        (Rate(4_000, 6_000), Rate(3_850, 6_000)),
        (Rate(9_000, 9_000), Rate(8_990, 9_000)),
        (Rate(5, 9_000), Rate(0, 9_000)),
    ]

    def tails() -> list[float]:
        return [stats.sign_test_p(*s) for s in signs] + [stats.below_p(*f) for f in fishers]

    fast = tails()
    monkeypatch.setattr(stats, "EXACT_TRIALS", 10**9)
    assert fast == pytest.approx(tails(), rel=1e-9, abs=1e-300)
    assert 0 < fast[0] < 1e-4 and fast[2] == 1.0 and fast[3] == 0.0 and 0 < fast[4] < 0.05


def test_two_expert_runs_from_other_seeds_do_not_pair(tmp_path, capsys):
    """``lerobot-pnp expert`` records each episode's seed: runs from --seed 0 and --seed 5000 are refused."""
    for name, seed in (("s0", "0"), ("s5000", "5000"), ("again", "0")):
        args = ["expert", "--env.task", "nominal", "--n_episodes", "2", "--seed", seed, "--progress", "false"]
        assert cli.main([*args, "--output_dir", str(tmp_path / name)]) == 0
    capsys.readouterr()
    assert cli.main(["compare", str(tmp_path / "s0"), str(tmp_path / "s5000")]) == 2
    err = capsys.readouterr().err
    assert "'s0' and run 's5000' were evaluated on other seeds" in err and "seed 0 vs 5000" in err
    assert cli.main(["compare", str(tmp_path / "s0"), str(tmp_path / "again")]) == 0
    assert "Every run records its episodes' seeds" in capsys.readouterr().out
