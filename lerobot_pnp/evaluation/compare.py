"""``lerobot-pnp compare RUN_A RUN_B ...``: the study's statistics over the ``eval_info.json`` of stock runs.

A run is one ``lerobot-eval`` output (its folder or its ``eval_info.json``), or several training seeds of one
method pooled: ``NAME=PATH[,PATH...]`` (how an argument splits, paths holding ``=`` or ``,`` included:
``compare_runs``). Any LeRobot benchmark's ``eval_info.json`` is read (``per_task``: a suite and task id per
entry, its ``successes`` per episode in seed order); the suites of this env's catalogue also get the control arm
and the held-out axes (disturbance and visual ones, ``suites.ALL_AXES``).

Pairing: ``lerobot-eval`` starts every task at ``--seed``, so episode ``i`` of every task and run is seed
``--seed + i``. Its ``eval_info.json`` records no seed, so runs pair by episode index: the runs compared must
share ``--seed``, and the command checks what the files allow, the same episode counts per task on every suite
they share, and the same seeds wherever files record them (``lerobot-pnp expert`` does); the page says which
runs were checked so. The numbers are the study's: pooled rates as ``results.pooled`` counts them (training seeds
pooled, Wilson intervals), per training seed the exact McNemar test of ``stats`` (the largest p reported as the
study's ``Comparison``), ``stats.paired_difference_interval`` and ``results.axis_result`` (the held-out verdict).
Outcomes are counted as arrays, so the cost grows linearly with the episodes.

Output: ``compare.md``, ``compare.json`` and ``compare.png`` are rendered first and then written as one set
(``OutputFolder.write_set``: all three or none, and only into files this command wrote before).
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lerobot_pnp.errors import ConfigError, one_line
from lerobot_pnp.evaluation.compare_runs import Run, check_control_seeds, pairs_of, parse_runs
from lerobot_pnp.evaluation.compare_text import difference_text, markdown, to_json
from lerobot_pnp.evaluation.stats import (
    PairedComparison,
    Rate,
    paired_difference_interval,
    seed_agreement,
    sign_test_p,
)
from lerobot_pnp.evaluation.verdicts import MARGIN
from lerobot_pnp.outputs import OutputFolder
from lerobot_pnp.sim.suites import ALL_AXES

__all__ = ["CompareConfig", "Run", "analyse", "difference_text", "parse_runs", "positional_runs", "run_compare"]

VERDICTS = ("improved", "regressed", "held", "underpowered")
DEFAULT_CONTROL = "nominal"  # the control arm's suite when --control is not given and the runs hold it
OUTPUTS = ("compare.md", "compare.json", "compare.png")

Outcomes = dict[str, dict[int, np.ndarray]]  # one file's suite -> task id -> per-episode successes


@dataclass
class CompareConfig:
    """``lerobot-pnp compare RUN [RUN ...]``: RUN is PATH or NAME=PATH[,PATH...] (training seeds pooled)."""

    # the runs (also given as positional arguments): PATH, or NAME=PATH[,PATH...] split at the first "=" and at
    # commas, except that an existing path is never split (a path may hold "=" and ",")
    runs: list[str] = field(default_factory=list)
    output_dir: str | None = None  # compare.md, compare.json and compare.png are written here (none: print only)
    alpha: float = 0.05  # significance level of the paired tests (every training seed's p below it)
    margin: float = MARGIN  # a difference whose 95 % interval lies within +-margin "held"; wider: "underpowered"
    control: str | None = None  # the suite each other suite is set beside (same seeds); none: nominal, if held
    suites: str | None = None  # only these suites, comma-separated (every run must hold them); none: all suites


def positional_runs(args: list[str]) -> list[str]:
    """``RUN_A RUN_B --flag v --flag=v`` -> the flags, then ``--runs=[...]`` (every compare flag takes a value)."""
    runs, rest, k = [], [], 0
    while k < len(args):
        arg = args[k]
        if not arg.startswith("-"):
            runs.append(arg)
        elif "=" not in arg and arg not in ("-h", "--help") and k + 1 < len(args):
            rest.append(f"{arg}={args[k + 1]}")
            k += 1
        else:
            rest.append(arg)
        k += 1
    return [*rest, f"--runs={json.dumps(runs)}"] if runs else rest


def _arrays(run: Run) -> list[Outcomes]:
    return [{s: {t: np.asarray(v, dtype=bool) for t, v in tasks.items()} for s, tasks in per.items()}
            for per in run.suites]  # fmt: skip


def _aligned(a: dict[int, np.ndarray], b: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The episodes two suites share, in the same order: of each task id both hold, the first episodes of both
    (episode ``i`` of every task is seed ``--seed + i``)."""
    shared = sorted(a.keys() & b.keys())
    m = [min(len(a[t]), len(b[t])) for t in shared]
    if not shared:
        return np.zeros(0, bool), np.zeros(0, bool)
    return np.concatenate([a[t][:k] for t, k in zip(shared, m)]), np.concatenate([b[t][:k] for t, k in zip(shared, m)])


def paired(arrays: dict, a: str, b: str, suite_a: str, suite_b: str, pairs: list[tuple[int, int]]) -> dict:
    """``a`` on ``suite_a`` minus ``b`` on ``suite_b`` on the same episodes: the study's per-seed comparisons
    (``stats.PairedComparison`` with its exact McNemar p, summed up as a ``results.Comparison``) and the pooled
    pairs' difference with its 95 % interval."""
    from lerobot_pnp.evaluation.results import Comparison

    comps, cells = [], [0, 0, 0, 0]  # both succeed, a only, b only, neither
    for ka, kb in pairs:
        x, y = _aligned(arrays[a][ka][suite_a], arrays[b][kb][suite_b])
        both, a_only, b_only = (int(np.count_nonzero(v)) for v in (x & y, x & ~y, ~x & y))
        comps.append(PairedComparison(len(x), a_only, b_only, sign_test_p(a_only, b_only)))
        for i, count in enumerate((both, a_only, b_only, len(x) - both - a_only - b_only)):
            cells[i] += count
    study = Comparison(sum(c.difference for c in comps) / len(comps), max(c.p_value for c in comps),
                       tuple(map(str, comps)))  # fmt: skip
    n = sum(cells)
    return {"n": n, "difference": (cells[1] - cells[2]) / n, "interval": paired_difference_interval(*cells),
            "study": study, "per_seed": comps}  # fmt: skip


def verdict(cmp: dict, alpha: float, margin: float) -> str:
    """improved / regressed: every training seed's paired test below ``alpha``, all in one direction; held: the
    pooled difference's interval within +-``margin``; underpowered: neither."""
    diffs = [c.difference for c in cmp["per_seed"]]
    if cmp["study"].max_p < alpha and all(d > 0 for d in diffs):
        return "improved"
    if cmp["study"].max_p < alpha and all(d < 0 for d in diffs):
        return "regressed"
    lo, hi = cmp["interval"]
    return "held" if -margin <= lo and hi <= margin else "underpowered"


def control_suite(runs: list[Run], control: str | None) -> str | None:
    """The control arm's suite: ``control`` (refused in one line unless some run holds it), or without one
    ``nominal`` where a run holds it (else no control arm)."""
    held = list(dict.fromkeys(s for r in runs for s in r.suites[0]))
    if control is None:
        return DEFAULT_CONTROL if DEFAULT_CONTROL in held else None
    if control not in held:
        raise ConfigError(f"compare: --control {control!r} is not a suite of the runs compared; valid: {sorted(held)}")
    return control


def _control_arm(runs: list[Run], arrays: dict, control: str | None) -> dict:
    """run -> suite -> that suite minus the control on the same seeds, for each run that holds the control."""
    arm: dict[str, dict] = {}
    for r in runs:
        arm[r.name] = {}
        if control is None or control not in r.suites[0]:
            continue
        for s, tasks in r.suites[0].items():
            if s == control:
                continue
            if not tasks.keys() & r.suites[0][control].keys():
                raise ConfigError(
                    f"compare: suite {s!r} of run {r.name!r} shares no task id with the control {control!r} (task ids "
                    f"{sorted(tasks)[:5]} vs {sorted(r.suites[0][control])[:5]}); give --control another suite, or "
                    f"leave {s!r} out with --suites"
                )
            check_control_seeds(r, s, control)
            arm[r.name][s] = paired(arrays, r.name, r.name, s, control, [(k, k) for k in range(len(r.paths))])
    return arm


def _pooled(per_path: list[Outcomes], suite: str):
    """The training seeds' rates on ``suite`` and their sum (``results.Pooled``, as ``results.pooled`` counts)."""
    from lerobot_pnp.evaluation.results import Pooled

    per = [Rate(int(sum(np.count_nonzero(v) for v in o[suite].values())), sum(len(v) for v in o[suite].values()))
           for o in per_path if suite in o]  # fmt: skip
    return Pooled(Rate(sum(p.successes for p in per), sum(p.n for p in per)), tuple(per)) if per else None


def analyse(runs: list[Run], cfg: CompareConfig) -> dict:
    """Every number of the comparison (rates, control arm, pairs of runs, held-out axes) as plain data."""
    from lerobot_pnp.evaluation.results import axis_result

    arrays = {r.name: _arrays(r) for r in runs}
    suites = list(dict.fromkeys(s for r in runs for s in r.suites[0]))
    table = {s: {r.name: p for r in runs if (p := _pooled(arrays[r.name], s))} for s in suites}
    control = control_suite(runs, cfg.control)
    pairs = []
    for i, ref in enumerate(runs):
        for other in runs[i + 1 :]:
            how = pairs_of(other, ref)
            for s in (s for s in suites if s in ref.suites[0] and s in other.suites[0]):
                cmp = paired(arrays, other.name, ref.name, s, s, how)
                pairs.append({"run": other.name, "reference": ref.name, "suite": s, **cmp,
                              "verdict": verdict(cmp, cfg.alpha, cfg.margin)})  # fmt: skip
    seeds = {r.name: {s: seed_agreement(cells[r.name].per_seed) for s, cells in table.items() if r.name in cells}
             for r in runs if len(r.paths) > 1}  # fmt: skip
    axes = [res for axis in ALL_AXES for r in runs if (res := axis_result(axis, r.name, table))]
    return {"runs": runs, "suites": suites, "table": table, "control_suite": control,
            "control": _control_arm(runs, arrays, control), "pairs": pairs, "seeds": seeds, "axes": axes}  # fmt: skip


def _plot(result: dict, cfg: CompareConfig) -> bytes:
    """compare.png's bytes, drawn in a temporary folder; run and suite names are drawn as written (matplotlib's
    mathtext off, so ``$`` is a dollar sign), and a figure that cannot be drawn is one line."""
    import matplotlib
    import matplotlib.pyplot as plt

    from lerobot_pnp.evaluation.plots import rate_bars

    rates = {r.name: {s: cells[r.name].rate for s, cells in result["table"].items() if r.name in cells}
             for r in result["runs"]}  # fmt: skip
    seeds = {n: {s: a.per_seed for s, a in per.items()} for n, per in result["seeds"].items()}
    figures = set(plt.get_fignums())
    with tempfile.TemporaryDirectory(prefix="lerobot_pnp_compare_") as tmp:
        try:
            with matplotlib.rc_context({"text.parse_math": False}):
                path = rate_bars(rates, Path(tmp) / "compare.png", "lerobot-pnp compare " + " ".join(cfg.runs),
                                 "success per suite", seeds)  # fmt: skip
        except (ValueError, RuntimeError) as err:
            for number in set(plt.get_fignums()) - figures:
                plt.close(number)
            raise ConfigError(f"compare: compare.png cannot be drawn ({one_line(err)}); nothing was written") from None
        return path.read_bytes()


def run_compare(cfg: CompareConfig) -> dict:
    """Read, check and compare the runs; write compare.md/.json/.png to ``output_dir`` as one set; print the
    markdown. Every input is checked and every file rendered before anything is written."""
    if not 0 < cfg.alpha < 1 or not 0 <= cfg.margin < 1:
        raise ConfigError(f"compare: alpha must be in (0, 1) and margin in [0, 1), got {cfg.alpha}, {cfg.margin}")
    result = analyse(parse_runs(cfg.runs, cfg.suites), cfg)
    text = markdown(result, cfg)
    written: list[str] = []
    if cfg.output_dir is not None:
        files = {"compare.md": text.encode(), "compare.json": json.dumps(to_json(result, cfg), indent=2).encode(),
                 "compare.png": _plot(result, cfg)}  # fmt: skip
        with OutputFolder(Path(cfg.output_dir), "lerobot-pnp compare") as out:
            written = [str(p) for p in out.write_set(files)]
    print(text)
    return {"written": written}
