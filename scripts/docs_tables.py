"""Regenerate every number and reference table of README.md and docs/ from the files they come from.

    python scripts/docs_tables.py          # rewrite the generated blocks and facts in place
    python scripts/docs_tables.py --check  # exit 1 and name the pages whose blocks differ (tests/test_docs_tables.py)

A page holds a generated block between two marker comments, ``<!-- begin generated: NAME -->`` and
``<!-- end generated: NAME -->`` (each on its own line), or a number its prose repeats between
``<!-- fact: NAME -->`` and ``<!-- /fact -->`` (``docs_facts.py``), and this script owns everything between them.
The result tables read the committed study summaries and measurement files under ``docs/results/`` (their
provenance, commit, date and machine, is in ``docs/results/sources.json`` and each summary's ``machine``); the
reference blocks (``docs_reference.py``) read the code itself (the suite catalogue, the CLI's ``--help``, the config dataclasses, the
module map), so a page can never drift from its source.
"""

from __future__ import annotations

import argparse
import json
import os
import posixpath
import re
import sys
from pathlib import Path

from lerobot_pnp.evaluation.verdicts import summary_verdict

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
BLOCK = re.compile(r"(<!-- begin generated: ([\w-]+) -->\n)(.*?)(<!-- end generated: \2 -->)", re.S)

# study method key -> column label (the report's own labels are longer than a table header should be)
PAPER_METHODS = {
    "expert": "expert (FSM)",
    "lookup_table": "lookup table",
    "clocked_lstm": "clocked LSTM (paper)",
    "memoryless_mlp": "memoryless MLP",
    "recovering": "recovering LSTM",
    "recovering_dagger": "+ DAgger",
    "recovering_dart": "+ DART",
    "act": "ACT",
}
PAPER_SUITES = ("nominal", "outside_ring", "nudge_0.03", "nudge_0.05", "obs_noise_0.01", "latency", "random_yaw",
                "grasp_miss", "drop", "displace")  # fmt: skip
HELDOUT_METHODS = ("recovering", "expert", "memoryless_mlp", "act", "lookup_table")  # the order of those run


def heldout_methods(summary: dict) -> list[str]:
    """The held-out study's methods, in the pages' order (``HELDOUT_METHODS``): those its config ran."""
    return [m for m in HELDOUT_METHODS if m in summary["config"]["methods"]]


def _json(rel: str) -> dict:
    return json.loads((RESULTS / rel).read_text())


def _pct(rate: float) -> str:
    return f"{100 * rate:.1f}".removesuffix(".0") if rate not in (0.0, 1.0) else f"{100 * rate:.0f}"


def _cell(c: dict, interval: bool = True) -> str:
    text = f"{_pct(c['rate'])} %"
    if interval:
        lo, hi = c["interval"]
        text += f" [{100 * lo:.1f}, {100 * hi:.1f}]"
    return text


def _machine(m: dict) -> str:
    return f"{m['cpu']}, {m['cores_available']} cores; LeRobot {m['lerobot']}, torch {m['torch']}, MuJoCo {m['mujoco']}"


def study_source() -> str:
    """The one line that names the run every study number comes from."""
    src = _json("sources.json")["study"]
    machine = _machine(_json(src["files"][0])["machine"])
    return f"Run: `{src['command']}` at commit `{src['commit']}`, {src['date']}, on {machine}."


def _source(name: str) -> str:
    s = _json("sources.json")[name]
    return f"Source: `docs/results/{name}`, commit `{s['commit']}`, {s['date']}, {s['machine']}."


# ------------------------------------------------------------------------------------------------ result tables
def paper_table(base: str) -> str:
    """Success % on the paper's task: the headline suites, the study's main methods, 3 training seeds pooled."""
    summary = _json("study/report_full/summary.json")
    success = summary["success"]
    head = "| suite | " + " | ".join(PAPER_METHODS.values()) + " |"
    lines = [head, "|---" * (len(PAPER_METHODS) + 1) + "|"]
    for suite in PAPER_SUITES:
        cells = [_pct(success[suite][m]["rate"]) for m in PAPER_METHODS]
        lines.append(f"| `{suite}` | " + " | ".join(cells) + " |")
    ns = [c["n"] for s in PAPER_SUITES for c in success[s].values()]
    seeds = summary["config"]["train_seeds"]
    return "\n".join(
        [
            *lines,
            "",
            f"Success %, task `paper`, {len(seeds)} training seeds pooled, {min(ns)}-{max(ns)} episodes per cell. "
            f"Each suite is described in the [suite catalogue]({posixpath.normpath(base + '../benchmark/suites.md')}) "
            "(95 % intervals, per-seed ranges and paired tests: "
            f"[the paper-task report]({base}study/report_full/report.md)). " + study_source(),
        ]
    )


def _verdict(entry: dict, difference: bool = False) -> str:
    v = summary_verdict(entry)
    text = f"**{v.text}**" if v.code != "no_verdict" else v.text
    lo, hi = v.interval
    return f"{text} ({100 * v.difference:+.1f} points [{100 * lo:+.1f}, {100 * hi:+.1f}])" if difference else text


def heldout_verdicts(base: str) -> str:
    """The recovering planner's verdict per disturbance axis of the held-out protocol."""
    from lerobot_pnp.sim.suites import HELD_OUT_AXES

    summary = _json("study/heldout/summary.json")
    rows = {(e["axis"], e["method"]): e for e in summary["held_out_axes"]}
    lines = ["| axis | in distribution | held out | lowest held-out suite | verdict |", "|---|---|---|---|---|"]
    for axis in HELD_OUT_AXES:
        e = rows[(axis.name, "recovering")]
        low_name, low = min(e["held_out_suites"].items(), key=lambda kv: kv[1]["rate"])
        sides = " | ".join(f"{_cell(e[side])} n={e[side]['n']}" for side in ("in_distribution", "held_out"))
        lines.append(
            f"| {axis.name} ({axis.description}) | {sides} | `{low_name}` {_cell(low, False)} | "
            f"{_verdict(e, difference=True)} |"
        )
    others = []
    for m in heldout_methods(summary)[1:]:
        verdicts = sorted({_verdict(e).strip("*") for (_, method), e in rows.items() if method == m})
        others.append(f"{PAPER_METHODS[m]}: {', '.join(verdicts)}")
    seeds = summary["config"]["train_seeds"]
    return "\n".join(
        [
            *lines,
            "",
            f"Recovering LSTM, task `full`, {len(seeds)} training seeds pooled (n: the episodes of a side's suites "
            f"and seeds), eval seeds from "
            f"{summary['config']['eval_seed']:,}. Other methods' verdicts on the five axes: {'; '.join(others)}. "
            + study_source(),
        ]
    )


def heldout_suites(base: str) -> str:
    """Every suite of the held-out study: the recovering planner with its interval and seeds, the baselines."""
    summary = _json("study/heldout/summary.json")
    cols = heldout_methods(summary)
    lines = ["| suite | " + " | ".join(PAPER_METHODS[m] for m in cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for suite, cells in summary["success"].items():
        rec = cells["recovering"]
        low, high = (_pct(r) for r in (min(rec["per_seed"]), max(rec["per_seed"])))
        first = f"{_cell(rec)} n={rec['n']}, " + (f"every seed {low} %" if low == high else f"seeds {low}-{high} %")
        rest = [f"{_pct(cells[m]['rate'])} %" if m in cells else "-" for m in cols[1:]]
        alias = summary["suite_aliases"].get(suite)
        name = f"`{suite}`" + (f" (= `{alias}`)" if alias else "")
        lines.append(f"| {name} | {first} | " + " | ".join(rest) + " |")
    return "\n".join([*lines, "", study_source()])


def _counted(k: int, n: int) -> str:
    """``k`` of ``n`` as a rate with its 95 % Wilson interval (the package's)."""
    from lerobot_pnp.evaluation.stats import wilson_interval

    return _cell({"rate": k / n, "interval": wilson_interval(k, n)})


def gate_table(base: str) -> str:
    """The observation gate on and off, the same weights: latency beyond the trained one step."""
    data = _json("recovering_gate_3seeds_eval.json")
    lines = ["| suite | gate on | gate off (same weights) |", "|---|---|---|"]
    for suite in ("train_latency", "heldout_latency_2", "heldout_latency_jitter"):
        counts = [
            [sum(r[suite][f] for r in data[arm].values()) for f in ("successes", "n")] for arm in ("gated", "ungated")
        ]
        lines.append(f"| `{suite}` | " + " | ".join(f"{_counted(k, n)} ({k}/{n})" for k, n in counts) + " |")
    return "\n".join([*lines, "", _source("recovering_gate_3seeds_eval.json")])


def memory_table(base: str) -> str:
    """Memory per attempt on and off, the same training and eval seeds."""
    data = _json("memory_per_attempt.json")
    lines = ["| suite | memory carried over the episode | memory per attempt |", "|---|---|---|"]
    for suite in ("nominal", "train_displace", "heldout_double_displace", "heldout_latency_2"):
        row = data["suites"][suite]
        cells = [_counted(row[arm], row["n"]) for arm in ("carried", "per_attempt")]
        lines.append(f"| `{suite}` (n={row['n']}) | " + " | ".join(cells) + " |")
    seeds = ", ".join(map(str, data["train_seeds"]))
    return "\n".join([*lines, "", f"Training seeds {seeds} pooled. " + _source("memory_per_attempt.json")])


def planner_table(base: str) -> str:
    """Clocked against recovering on a task with recovery demonstrations, and the memoryless controls."""
    data = _json("planner_evals.json")
    suites = ("nominal", "grasp_miss", "drop", "displace", "noise_latency")
    rows = {
        "clocked (paper), 10-frame demos": "clocked (paper)",
        "recovering, round 0": "recovering",
        "memoryless MLP, with late episodes": "memoryless MLP",
        "memoryless MLP told the phase, current observations only": "memoryless MLP told the phase",
    }
    lines = ["| policy | " + " | ".join(f"`{s}`" for s in suites) + " |", "|---" * (len(suites) + 1) + "|"]
    for key, label in rows.items():
        cells = [data["rows"][key][s] for s in suites]
        lines.append(f"| {label} | " + " | ".join(f"{_pct(c['successes'] / c['n'])}" for c in cells) + " |")
    return "\n".join(
        [
            *lines,
            "",
            f"Success %, {data['episodes_per_suite']} episodes per suite, one training seed, the same eval seeds "
            "for every row. " + _source("planner_evals.json"),
        ]
    )


def leaderboard_table(base: str) -> str:
    """The leaderboard's page in one compact table, the page's numbers; the untrained floor is on the page only."""
    from lerobot_pnp.evaluation.leaderboard import readme_block

    return readme_block(ROOT, docs=base + "../", leave_out=("untrained_pnp_lstm",))


# ----------------------------------------------------------------------------------------------------- render
sys.path.insert(0, str(Path(__file__).resolve().parent))
from architecture import BLOCKS as ARCHITECTURE_BLOCKS  # noqa: E402  (docs/ARCHITECTURE.md's module map)
from docs_command_costs import BLOCKS as COMMAND_COST_BLOCKS  # noqa: E402  (docs/costs.md: each command's cost)
from docs_cost import BLOCKS as COST_BLOCKS  # noqa: E402  (what make demo and make study cost)
from docs_facts import FACT, render_facts  # noqa: E402  (the numbers prose repeats, one line each)
from docs_pixel_tables import BLOCKS as PIXEL_BLOCKS  # noqa: E402  (the camera planner page's blocks)
from docs_reference import BLOCKS as REFERENCE_BLOCKS  # noqa: E402  (read from the code: CLI help, config fields)
from docs_visual_tables import BLOCKS as VISUAL_BLOCKS  # noqa: E402  (the visual axes' ranges)

BLOCKS = {
    **PIXEL_BLOCKS, **ARCHITECTURE_BLOCKS, **REFERENCE_BLOCKS, **COST_BLOCKS, **COMMAND_COST_BLOCKS, **VISUAL_BLOCKS,
    "paper-table": paper_table,
    "heldout-verdicts": heldout_verdicts, "heldout-suites": heldout_suites, "gate-table": gate_table,
    "memory-table": memory_table, "planner-table": planner_table, "leaderboard": leaderboard_table,
}  # fmt: skip


def pages() -> list[Path]:
    """README.md and every hand-written page of docs/ (a study's own report.md is written by the study)."""
    docs = [p for p in sorted((ROOT / "docs").rglob("*.md")) if "study" not in p.relative_to(RESULTS.parent).parts]
    return [ROOT / "README.md", *docs]


def render(page: Path, text: str, cache: dict[tuple[str, str], str]) -> str:
    """``text`` with every generated block and fact of ``page`` regenerated; an unknown name is an error."""
    base = os.path.relpath(RESULTS, page.parent).replace(os.sep, "/") + "/"

    def fill(m: re.Match) -> str:
        name = m.group(2)
        if name not in BLOCKS:
            raise SystemExit(f"{page.relative_to(ROOT)}: unknown generated block {name!r}; valid: {sorted(BLOCKS)}")
        if (name, base) not in cache:
            cache[(name, base)] = BLOCKS[name](base)
        return f"{m.group(1)}{cache[(name, base)]}\n{m.group(4)}"

    return render_facts(page, BLOCK.sub(fill, text), cache)


def regenerate() -> dict[Path, tuple[str, str]]:
    """Every page that holds a generated block or fact -> (its text now, its text regenerated)."""
    cache: dict[tuple[str, str], str] = {}
    out = {}
    for page in pages():
        text = page.read_text()
        if BLOCK.search(text) or FACT.search(text):
            out[page] = (text, render(page, text, cache))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 if a page differs")
    args = parser.parse_args(argv)
    stale = []
    for page, (old, new) in regenerate().items():
        if old != new:
            stale.append(str(page.relative_to(ROOT)))
            if not args.check:
                page.write_text(new)
    if args.check and stale:
        print("generated blocks differ from their sources (run python scripts/docs_tables.py): " + ", ".join(stale))
        return 1
    print(("stale: " if args.check else "rewritten: ") + (", ".join(stale) or "none"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
