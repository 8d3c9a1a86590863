"""The numbers a page's prose repeats, generated from the result files: one source per headline number.

A page states such a number between two markers on one line::

    ... its nominal rate, <!-- fact: pixel-protocol-nominal -->86.3 % [83.4, 88.9]<!-- /fact -->, ...

and ``scripts/docs_tables.py`` rewrites what lies between them from the fact's source, as it does a generated
block (``--check``: exit 1 when a page differs). The markers are HTML comments: GitHub and the site show the
number alone. The same fact on two pages is one value, and ``tests/test_docs_numbers.py`` fails when a page
restates a fact's quantity by hand (each fact's ``restated`` pattern) or types a rate with its interval that no
result file gives.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
FACT = re.compile(r"(<!-- fact: ([\w-]+) -->)(.*?)(<!-- /fact -->)")


@dataclass(frozen=True)
class Fact:
    """A number a page repeats: where it comes from, and the phrase that restates it by hand (``restated``: a
    regular expression; outside the fact's markers, a match on any page fails the agreement test)."""

    value: Callable[[], str]
    restated: str = ""


def _json(rel: str) -> dict:
    return json.loads((RESULTS / rel).read_text())


def _config(study: str) -> dict:
    return _json(f"study/{study}/summary.json")["config"]


def _train(study: str) -> str:
    from lerobot_pnp.dataset.splits import train_count

    return str(train_count(_config(study)["num_episodes"]))


def _pixel_protocol_nominal() -> str:
    """The camera planner's newest 3-seed protocol: its pooled nominal rate, seeds and episodes."""
    from docs_pixel_tables import PROTOCOLS, _rate

    cell = _json(f"{PROTOCOLS[0][0]}/compare/compare.json")["success"]["nominal"]["camera_planner"]
    seeds = len(cell["per_seed"])
    return f"{_rate(cell)} ({seeds} seeds x {cell['n'] // seeds} episodes)"


def _pixel_leaderboard_runs() -> str:
    """The camera planner's leaderboard row: its training seeds and the episodes per suite of each."""
    runs = sorted((RESULTS / "leaderboard" / "pnp_pixels").glob("seed*/eval_info.json"))
    per_suite = {g["n_episodes"] for r in runs for g in json.loads(r.read_text())["per_group"].values()}
    if len(per_suite) != 1:
        raise SystemExit(f"docs/results/leaderboard/pnp_pixels: the seeds' episodes per suite differ: {per_suite}")
    return f"{len(runs)} training seeds pooled, {per_suite.pop()} episodes per suite"


def _demo_demos() -> str:
    from lerobot_pnp.report.config import PRESETS

    return str(PRESETS["demo"]["num_episodes"])


def _cell(study: str, suite: str, method: str) -> dict:
    return _json(f"study/{study}/summary.json")["success"][suite][method]


def _rate(study: str, suite: str, method: str, n: bool = False) -> str:
    """A method's pooled success on one suite of a study, as the tables write it ("99.7 %"), with its episodes."""
    cell = _cell(study, suite, method)
    pct = f"{100 * cell['rate']:.1f}".removesuffix(".0")
    return f"{pct} %" + (f" of {cell['n']} episodes" if n else "")


def _failures(study: str, label: str, suite: str) -> tuple[dict[str, int], dict[str, int]]:
    """(failures by cause, failures by furthest phase) of one method on one suite: the study report's
    "Failures by cause" table (its summary.json keeps success only)."""
    report = (RESULTS / "study" / study / "report.md").read_text()
    row = re.search(rf"^\| {re.escape(label)} \| `{re.escape(suite)}` \| ([^|]*) \| ([^|]*) \|$", report, re.M)
    if row is None:
        raise SystemExit(f"docs/results/study/{study}/report.md: no failures row for {label!r} on {suite!r}")
    return tuple({k: int(v) for k, v in re.findall(r"([\w/]+) (\d+)", row.group(i))} for i in (1, 2))


def _failed_at(study: str, label: str, method: str, suite: str, phase: str, of: bool = True) -> str:
    """How many of a method's episodes on ``suite`` ended with ``phase`` the furthest one reached ("129 of 150")."""
    count = _failures(study, label, suite)[1].get(phase, 0)
    return f"{count} of {_cell(study, suite, method)['n']}" if of else str(count)


FACTS: dict[str, Fact] = {
    # the paper-task study's demonstrations (its summary's config) and the training split the generator makes
    "paper-demos": Fact(lambda: str(_config("report_full")["num_episodes"]),
                        r"\b[\d,]+ (?:demonstrations|demos) of the paper's task"),
    "paper-train-demos": Fact(lambda: _train("report_full"), r"\b[\d,]+ of them in the training split"),
    "demo-demos": Fact(_demo_demos, r"the paper's [\d,]+ demonstrations"),
    "pixel-protocol-nominal": Fact(_pixel_protocol_nominal, r"(?:200|two-hundred)-episode protocol \("),
    "pixel-leaderboard-runs": Fact(_pixel_leaderboard_runs),
    # what the numbers mean (docs/numbers.md): the lookup table on both tasks, the memoryless controls' failures
    "lookup-paper-nominal": Fact(lambda: _rate("report_full", "nominal", "lookup_table"),
                                 r"lookup table (?:scores|gets|reaches) [\d.]+ ?%"),
    "lookup-paper-outside-ring": Fact(lambda: _rate("report_full", "outside_ring", "lookup_table")),
    "lookup-full-nominal": Fact(lambda: _rate("heldout", "nominal", "lookup_table", n=True)),
    "lookup-full-never-near": Fact(lambda: _failed_at("heldout", "lookup table", "lookup_table", "nominal",
                                                      "pick/start")),
    "lookup-full-dropped": Fact(lambda: str(_failures("heldout", "lookup table", "nominal")[0].get("dropped", 0))),
    "clocked-paper-nominal": Fact(lambda: _rate("report_full", "nominal", "clocked_lstm")),
    "clocked-reset-paper-nominal": Fact(lambda: _rate("report_full", "nominal", "memoryless")),
    "mlp-paper-nominal": Fact(lambda: _rate("report_full", "nominal", "memoryless_mlp", n=True),
                              r"memoryless MLP (?:scores|gets|reaches) [\d.]+ ?%"),
    "mlp-paper-grasp": Fact(lambda: _failed_at("report_full", "memoryless MLP (matched)", "memoryless_mlp", "nominal",
                                               "pick/grasp")),
    "mlp-paper-retract": Fact(lambda: _failed_at("report_full", "memoryless MLP (matched)", "memoryless_mlp",
                                                 "nominal", "pick/retract", of=False)),
    "told-paper-nominal": Fact(lambda: _rate("report_full", "nominal", "phase_told_mlp")),
    "told-paper-retract": Fact(lambda: _failed_at("report_full", "MLP told the phase", "phase_told_mlp", "nominal",
                                                  "pick/retract")),
    "told-paper-grasp": Fact(lambda: _failed_at("report_full", "MLP told the phase", "phase_told_mlp", "nominal",
                                                "pick/grasp", of=False)),
    "told-paper-slack": Fact(lambda: _rate("report_full", "slack", "phase_told_mlp")),
    "recovering-paper-slack": Fact(lambda: _rate("report_full", "slack", "recovering")),
}  # fmt: skip


def render_facts(page: Path, text: str, cache: dict) -> str:
    """``text`` with every fact's value regenerated; an unknown fact is an error naming the valid ones, and so is a
    fact that opens a line (Markdown reads a line that starts with an HTML comment as raw HTML, which ends a list
    item or a paragraph there)."""

    def fill(m: re.Match) -> str:
        name = m.group(2)
        if name not in FACTS:
            raise SystemExit(f"{page.relative_to(ROOT)}: unknown fact {name!r}; valid: {sorted(FACTS)}")
        if ("fact", name) not in cache:
            cache[("fact", name)] = FACTS[name].value()
        return f"{m.group(1)}{cache[('fact', name)]}{m.group(4)}"

    text = FACT.sub(fill, text)
    if m := re.search(r"^[ \t]*<!-- fact: ([\w-]+) -->", text, re.M):
        line = text[: m.start()].count("\n") + 1
        raise SystemExit(f"{page.relative_to(ROOT)}:{line}: fact {m.group(1)!r} opens a line; put a word before it")
    return text
