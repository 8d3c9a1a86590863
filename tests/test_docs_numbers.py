"""One source per number: the rates, intervals, data budgets and training times that README.md and docs/ state about
committed results agree with the result files under docs/results/ and with each other.

- A summary page (the README, the guides, the results overview) states a rate with its 95 % interval only in
  generated text: a block or a fact of ``scripts/docs_tables.py``, regenerated from its source file.
- Any other rate with an interval typed on a page (a result page's prose) is one that a committed result file gives.
- A quantity a fact carries (``scripts/docs_facts.py``: the studies' demonstrations, the camera planner's protocol
  rate) is not restated by hand anywhere.
- The leaderboard's budget column names the data, seeds and training time of the run its row describes: the same
  numbers as the study summary or protocol record that run comes from.
- The held-out axes have one vocabulary, ``evaluation/verdicts.py``'s.

The changelog is a record of earlier runs and is left out; pages a command writes (a study's report.md,
``lerobot-pnp compare``'s compare.md, ``lerobot-pnp leaderboard``'s page) are checked against their inputs by their
own tests and count here as sources.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest
from clis import load_script

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
# a success rate with its 95 % interval: "86.3 % [83.4, 88.9]", "85.7% [81.2, 89.2]", "100 [96.3, 100]"; a signed
# difference ("+8.3 [3.7, 12.9]", "-3.7 points [...]") is not one
RATE = re.compile(r"(?<![\d.+\-−])(\d{1,3}(?:\.\d+)?)(?: ?%)? \[(\d{1,3}(?:\.\d+)?), (\d{1,3}(?:\.\d+)?)\]")
BLOCK = re.compile(r"<!-- begin generated: ([\w-]+) -->\n.*?<!-- end generated: \1 -->", re.S)
RETIRED_VERDICTS = ("only partly", "degrades", "no_recovery", "partly generalises")


@pytest.fixture(scope="module")
def dt():
    return load_script("scripts/docs_tables.py")


@pytest.fixture(scope="module")
def facts(dt):
    import docs_facts  # on the path docs_tables.py sets: the module it renders facts with

    return docs_facts


def _machine_written(rel: str) -> bool:
    return rel == "docs/leaderboard.md" or rel.endswith("/compare.md") or rel.startswith("docs/results/study/")


def _pages() -> dict[str, str]:
    """Every page but the changelog, by its path from the repository root."""
    paths = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    return {str(p.relative_to(ROOT)): p.read_text() for p in paths if p.name != "changelog.md"}


def _hand_written(text: str, facts) -> str:
    """A page's text without its generated blocks and facts."""
    return facts.FACT.sub("FACT", BLOCK.sub("BLOCK", text))


def _summary(rel: str) -> bool:
    """A page that repeats results rather than reporting its own: all but the result pages under docs/results/."""
    detail = rel.startswith("docs/results/") and rel not in ("docs/results/index.md", "docs/results/reproduce.md")
    return not detail and not _machine_written(rel)


def _rates(text: str) -> list[tuple[float, float, float]]:
    return [tuple(float(x) for x in m.groups()) for m in RATE.finditer(text)]


# ------------------------------------------------------------------------------------------------- sources
def _add(out: set, k: float, n: int) -> None:
    from lerobot_pnp.evaluation.stats import wilson_interval

    k = round(k)
    if n > 0 and 0 <= k <= n:
        lo, hi = wilson_interval(k, n)
        out.add((100 * k / n, 100 * lo, 100 * hi))


def _walk(x, out: set) -> None:
    """Every rate with an interval a result file holds: counts (successes of n, a success percentage of n
    episodes), rates with their intervals, and rates written out in its strings."""
    if isinstance(x, dict):
        if isinstance(x.get("successes"), int | float) and isinstance(x.get("n"), int):
            _add(out, x["successes"], x["n"])
        if isinstance(x.get("pc_success"), int | float) and isinstance(x.get("n_episodes"), int):
            _add(out, x["pc_success"] * x["n_episodes"] / 100, x["n_episodes"])
        if isinstance(x.get("rate"), float | int) and isinstance(x.get("interval"), list):
            out.add((100 * x["rate"], *(100 * v for v in x["interval"])))
        if isinstance(x.get("success_pct"), float | int) and isinstance(x.get("wilson95_pct"), list):
            out.add((x["success_pct"], *x["wilson95_pct"]))
        for v in x.values():
            _walk(v, out)
    elif isinstance(x, list):
        if x and all(isinstance(v, bool) for v in x):
            _add(out, sum(x), len(x))
        for v in x:
            _walk(v, out)
    elif isinstance(x, str):
        out.update(_rates(x))


@pytest.fixture(scope="module")
def sourced(facts) -> set:
    """Every rate with an interval that a source states: the result files, generated text, pages a command wrote."""
    out: set = set()
    for path in RESULTS.rglob("*.json"):
        _walk(json.loads(path.read_text()), out)
    for rel, text in _pages().items():
        generated = text if _machine_written(rel) else "\n".join(m.group(0) for m in BLOCK.finditer(text))
        out.update(_rates(generated + "\n".join(m.group(0) for m in facts.FACT.finditer(text))))
    return out


def _given(rate: tuple, sourced: set) -> bool:
    return any(all(abs(a - b) <= 0.051 for a, b in zip(rate, s, strict=True)) for s in sourced)


# --------------------------------------------------------------------------------------------------- tests
def test_summary_pages_state_a_rate_with_its_interval_only_in_generated_text(facts):
    typed = {rel: _rates(_hand_written(text, facts)) for rel, text in _pages().items() if _summary(rel)}
    typed = {rel: rates for rel, rates in typed.items() if rates}
    assert not typed, f"state these through a generated block or a fact (scripts/docs_facts.py): {typed}"


def test_every_rate_with_an_interval_typed_on_a_page_is_one_a_result_file_gives(facts, sourced):
    assert len(sourced) > 500  # the result files were read
    wrong = {}
    for rel, text in _pages().items():
        if not _machine_written(rel):
            bad = [r for r in _rates(_hand_written(text, facts)) if not _given(r, sourced)]
            if bad:
                wrong[rel] = bad
    assert not wrong, f"rates with intervals that no file under docs/results/ gives: {wrong}"


def test_a_mistyped_interval_is_caught(facts, sourced):
    """The checks above fail on the contradictions they are for: a number retyped by hand on a summary page, and a
    rate whose interval no file gives."""
    readme = (ROOT / "README.md").read_text() + "\nThe camera planner reaches 85.7 [75.3, 96.0] nominal.\n"
    assert _rates(_hand_written(readme, facts)) == [(85.7, 75.3, 96.0)]
    assert _given((85.7, 75.3, 96.0), sourced) and not _given((85.7, 75.3, 96.2), sourced)
    assert _rates("+8.3 [3.7, 12.9] and -3.7 points [-5.5, -1.4]") == []


def test_every_fact_is_used_and_a_hand_edited_one_is_restored(dt, facts):
    pages = _pages()
    used = {m.group(2) for text in pages.values() for m in facts.FACT.finditer(text)}
    assert used == set(facts.FACTS)
    page = ROOT / "docs" / "results" / "index.md"
    text = page.read_text()
    edited = text.replace(
        "<!-- fact: paper-demos -->1400<!-- /fact -->", "<!-- fact: paper-demos -->1000<!-- /fact -->"
    )
    assert edited != text and dt.render(page, edited, {}) == dt.render(page, text, {})
    with pytest.raises(SystemExit, match="unknown fact 'nope'"):
        dt.render(page, "<!-- fact: nope -->1<!-- /fact -->", {})


def test_a_facts_quantity_is_not_restated_by_hand(facts):
    restated = {}
    for rel, text in _pages().items():
        if _machine_written(rel):
            continue
        hand = _hand_written(text, facts)
        for name, fact in facts.FACTS.items():
            if fact.restated and (m := re.search(fact.restated, hand)):
                restated.setdefault(rel, []).append(f"{name}: {m.group(0)!r}")
    assert not restated, f"state these through their fact (<!-- fact: NAME -->...<!-- /fact -->): {restated}"
    assert re.search(facts.FACTS["paper-demos"].restated, "from the same 1400 demonstrations of the paper's task")


def _row(name: str) -> dict:
    return json.loads((RESULTS / "leaderboard" / name / "row.json").read_text())


def _study(label: str) -> str:
    return "report_full" if "paper-task study" in label else "heldout"


@pytest.mark.parametrize(("row", "method"), [("clocked_lstm", "clocked_lstm"), ("act", "act"),
                                             ("recovering_lstm", "recovering"), ("lookup_table", None)])  # fmt: skip
def test_a_leaderboard_budget_states_the_data_and_training_time_of_its_study(row, method):
    """A row trained as a study trains: its budget's demonstrations are that study's, its label's training episodes
    that study's training split, and a study-timed training the time the study's summary records for its seed."""
    from lerobot_pnp.dataset.splits import train_count

    budget, label = _row(row)["budget"], _row(row)["label"]
    summary = json.loads((RESULTS / "study" / _study(label) / "summary.json").read_text())
    demos = summary["config"]["num_episodes"]
    assert int(re.match(r"(\d+) ", budget).group(1)) == demos, budget
    assert {int(n) for n in re.findall(r"(\d+) demonstrations", label)} == {demos}, label
    if m := re.search(r"(\d+) training episodes", label):
        assert int(m.group(1)) == train_count(demos), label
    if m := re.search(r"~(\d+(?:\.\d+)?) min \(study\)", budget):
        seed = re.search(r"training seed (\d+)", label).group(1)
        assert float(m.group(1)) == round(summary["timings_s"][f"train/{method}/{seed}"] / 60, 1), budget


def test_the_camera_planners_budget_states_its_protocols_data_seeds_and_training_times():
    PROTOCOLS = load_script("scripts/docs_pixel_tables.py").PROTOCOLS

    folder, demos, _, _ = PROTOCOLS[0]
    budget = _row("pnp_pixels")["budget"]
    protocol = json.loads((RESULTS / folder / "protocol.json").read_text())
    minutes = [run["train_time_s"] / 60 for name, run in protocol["train"].items() if name.startswith("camera_seed")]
    seeds = sorted((RESULTS / "leaderboard" / "pnp_pixels").glob("seed*"))
    assert budget.startswith(f"{demos} demos,"), budget
    assert f"{len(seeds)} seeds" in budget and len(minutes) == len(seeds), budget
    assert f"{math.floor(min(minutes))}-{math.ceil(max(minutes))} min each" in budget, (budget, minutes)


def test_the_camera_planners_row_reproduces_from_its_command_and_config():
    """The row's seeds trained on one torch thread each and its command runs the shipped config without a thread
    flag, so the config trains on one thread (the page says the thread count changes the result)."""
    row = _row("pnp_pixels")
    config = json.loads((ROOT / "configs" / "train_pnp_pixels.json").read_text())
    assert "configs/train_pnp_pixels.json" in row["command"] and "torch_num_threads" not in row["command"]
    assert "each seed on one torch thread" in row["label"]
    assert config["policy"]["torch_num_threads"] == 1


def test_a_quoted_leaderboard_budget_is_the_rows(facts):
    budgets = {_row(p.parent.name).get("budget") for p in (RESULTS / "leaderboard").glob("*/row.json")}
    quoted = {rel: re.findall(r"leaderboard's budget \(\"([^\"]+)\"\)", text) for rel, text in _pages().items()}
    wrong = {rel: [q for q in qs if not any(q in b for b in budgets if b)] for rel, qs in quoted.items()}
    assert not {rel: qs for rel, qs in wrong.items() if qs}


def test_the_held_out_axes_have_one_vocabulary():
    """Every page words an axis verdict as ``verdicts.TEXT`` does; a study's report.md keeps the words of the commit
    it ran at (docs/results/index.md says so), and the tables generated from its summary apply today's rule."""
    from lerobot_pnp.evaluation.verdicts import TEXT

    pages = {rel: text for rel, text in _pages().items() if not rel.startswith("docs/results/study/")}
    retired = {rel: [w for w in RETIRED_VERDICTS if w in text.lower()] for rel, text in pages.items()}
    assert not {rel: ws for rel, ws in retired.items() if ws}, f"say it with {sorted(TEXT.values())}"
    heldout = (ROOT / "docs" / "benchmark" / "heldout.md").read_text()
    for text in TEXT.values():
        assert f"**{text}**" in heldout, text


def test_a_fact_that_opens_a_line_is_refused(facts):
    """Markdown reads a line that starts with an HTML comment as raw HTML: a fact there would end its list item."""
    page = ROOT / "docs" / "numbers.md"
    with pytest.raises(SystemExit, match="numbers.md:2: fact 'paper-demos' opens a line"):
        facts.render_facts(page, "- a list item,\n  <!-- fact: paper-demos -->1<!-- /fact --> more\n", {})
    assert "1400" in facts.render_facts(page, "- a list item, <!-- fact: paper-demos -->1<!-- /fact -->\n", {})
