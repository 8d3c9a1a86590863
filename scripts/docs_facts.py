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


FACTS: dict[str, Fact] = {
    # the paper-task study's demonstrations (its summary's config) and the training split the generator makes
    "paper-demos": Fact(lambda: str(_config("report_full")["num_episodes"]),
                        r"\b[\d,]+ (?:demonstrations|demos) of the paper's task"),
    "paper-train-demos": Fact(lambda: _train("report_full"), r"\b[\d,]+ of them in the training split"),
    "demo-demos": Fact(_demo_demos, r"the paper's [\d,]+ demonstrations"),
    "pixel-protocol-nominal": Fact(_pixel_protocol_nominal, r"(?:200|two-hundred)-episode protocol \("),
    "pixel-leaderboard-runs": Fact(_pixel_leaderboard_runs),
}  # fmt: skip


def render_facts(page: Path, text: str, cache: dict) -> str:
    """``text`` with every fact's value regenerated; an unknown fact is an error naming the valid ones."""

    def fill(m: re.Match) -> str:
        name = m.group(2)
        if name not in FACTS:
            raise SystemExit(f"{page.relative_to(ROOT)}: unknown fact {name!r}; valid: {sorted(FACTS)}")
        if ("fact", name) not in cache:
            cache[("fact", name)] = FACTS[name].value()
        return f"{m.group(1)}{cache[('fact', name)]}{m.group(4)}"

    return FACT.sub(fill, text)
