"""``lerobot-pnp compare RUN_A RUN_B ...``: the study's statistics over the ``eval_info.json`` of stock runs.

A run is one ``lerobot-eval`` output (its folder or its ``eval_info.json``), or several training seeds of one
method pooled: ``NAME=PATH[,PATH...]``. Any LeRobot benchmark's ``eval_info.json`` is read (``per_task``: a suite
and task id per entry, its ``successes`` per episode in seed order); the suites of this env's catalogue also get
the control arm and the held-out axes.

Pairing: ``lerobot-eval`` starts every task at ``--seed``, so episode ``i`` of every task and run is seed
``--seed + i``. ``eval_info.json`` records no seed, so runs pair by episode index: the runs compared must share
``--seed``, and the command checks what the files allow, the same episode counts per task on every suite they
share. Everything is computed by the study's code: ``results.pooled`` (training seeds pooled, Wilson intervals),
``stats.paired_comparison`` (exact McNemar per training seed, the largest p reported as the study's
``Comparison``), ``stats.paired_difference_interval`` and ``results.axis_result`` (the held-out verdict).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.records import EpisodeRecord
from lerobot_pnp.evaluation.stats import paired_comparison, paired_difference_interval, seed_agreement
from lerobot_pnp.evaluation.suites import HELD_OUT_AXES

TASK_STRIDE = 1_000_000  # an episode's key: task_id * TASK_STRIDE + its index (its seed is --seed + index)
VERDICTS = ("improved", "regressed", "held", "underpowered")


@dataclass
class CompareConfig:
    """``lerobot-pnp compare RUN [RUN ...]``: RUN is PATH or NAME=PATH[,PATH...] (training seeds pooled)."""

    runs: list[str] = field(default_factory=list)  # the runs (also given as positional arguments)
    output_dir: str | None = None  # compare.md, compare.json and compare.png are written here (none: print only)
    alpha: float = 0.05  # significance level of the paired tests (every training seed's p below it)
    margin: float = 0.05  # a difference whose 95 % interval lies within +-margin "held"; wider: "underpowered"
    control: str = "nominal"  # the unperturbed suite each other suite is set beside (same seeds)
    suites: str | None = None  # only these suites, comma-separated (every run must hold them); none: all suites


@dataclass(frozen=True)
class Run:
    name: str
    paths: tuple[str, ...]
    suites: tuple[dict[str, dict[int, list[bool]]], ...]  # per path: suite -> task id -> successes


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


def read_eval_info(path: str | Path) -> dict[str, dict[int, list[bool]]]:
    """suite -> task id -> per-episode successes of one ``eval_info.json`` (a folder holding it, or the file)."""
    file = Path(path) / "eval_info.json" if Path(path).is_dir() else Path(path)
    if not file.is_file():
        raise ConfigError(f"compare: no eval_info.json at {path}")
    try:
        data = json.loads(file.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ConfigError(f"compare: {file} is not JSON ({err})") from None
    foreign = f"compare: {file} is not a lerobot-eval eval_info.json"
    if not isinstance(data, dict) or not isinstance(data.get("per_task"), list) or not data["per_task"]:
        raise ConfigError(f"{foreign} (no per_task list)")
    out: dict[str, dict[int, list[bool]]] = {}
    for entry in data["per_task"]:
        try:
            group, task_id, successes = entry["task_group"], entry["task_id"], entry["metrics"]["successes"]
        except (TypeError, KeyError):
            raise ConfigError(f"{foreign} (a per_task entry without task_group, task_id, metrics.successes)") from None
        if not isinstance(group, str) or not isinstance(task_id, int) or not isinstance(successes, list):
            raise ConfigError(f"{foreign} (per_task entry {entry.get('task_group')!r}: wrong types)")
        if not successes or any(s not in (True, False, 0, 1) for s in successes) or task_id in out.get(group, {}):
            raise ConfigError(f"{foreign} (suite {group!r} task {task_id}: no episodes, non-boolean or repeated)")
        out.setdefault(group, {})[task_id] = [bool(s) for s in successes]
    for group, stats in (data.get("per_group") or {}).items():  # stock eval writes both: they must agree
        n = sum(len(v) for v in out.get(group, {}).values())
        if not isinstance(stats, dict) or stats.get("n_episodes") != n:
            raise ConfigError(f"{foreign} (per_group[{group!r}] does not count the {n} episodes of per_task)")
    return out


def _counts(suites: dict[str, dict[int, list[bool]]]) -> dict[str, dict[int, int]]:
    return {s: {t: len(v) for t, v in tasks.items()} for s, tasks in suites.items()}


def _only(suites: dict[str, dict[int, list[bool]]], keep: list[str] | None, path: str) -> dict:
    """The suites named in ``keep`` (all when None); a run that lacks one is refused, naming what it holds."""
    if keep is None:
        return suites
    missing = [s for s in keep if s not in suites]
    if missing:
        raise ConfigError(f"compare: {path} holds no suite {missing[0]!r}; it holds {sorted(suites)}")
    return {s: suites[s] for s in keep}


def _read_run(spec: str, keep: list[str] | None = None) -> Run:
    name, _, paths = spec.rpartition("=") if "=" in spec else (Path(spec).name or spec, "", spec)
    parts = tuple(p for p in paths.split(",") if p)
    if not name or not parts:
        raise ConfigError(f"compare: run {spec!r} is not PATH or NAME=PATH[,PATH...]")
    suites = tuple(_only(read_eval_info(p), keep, p) for p in parts)
    for p, s in zip(parts[1:], suites[1:], strict=True):
        if _counts(s) != _counts(suites[0]):
            raise ConfigError(f"compare: run {name!r}: {p} does not hold the suites and episode counts of {parts[0]}")
    return Run(name, parts, suites)


def parse_runs(specs: list[str], suites: str | None = None) -> list[Run]:
    """Each spec read and checked: a run's paths hold the same tasks and counts (its training seeds pool on the
    same episodes); runs share at least one suite, with the same counts on every suite they share. ``suites``
    (comma-separated) keeps only those suites of every path, so that runs evaluated on different sets of
    suites pool and pair on the ones they share."""
    if not specs:
        raise ConfigError("compare: give at least one run (PATH or NAME=PATH[,PATH...])")
    keep = None if suites is None else [s.strip() for s in suites.split(",") if s.strip()]
    if keep is not None and not keep:
        raise ConfigError("compare: suites is empty; give suite names, comma-separated")
    runs = [_read_run(spec, keep) for spec in specs]
    if len({r.name for r in runs}) != len(runs):
        raise ConfigError(f"compare: run names repeat: {[r.name for r in runs]}; name them NAME=PATH")
    for i, a in enumerate(runs):
        for b in runs[i + 1 :]:
            ca, cb = _counts(a.suites[0]), _counts(b.suites[0])
            shared = set(ca) & set(cb)
            if not shared:
                raise ConfigError(f"compare: runs {a.name!r} and {b.name!r} share no suite")
            bad = sorted(s for s in shared if ca[s] != cb[s])
            if bad:
                raise ConfigError(
                    f"compare: runs {a.name!r} and {b.name!r} do not pair on {bad[:3]}"
                    f"{f' and {len(bad) - 3} more suites' if len(bad) > 3 else ''}: episodes per task {ca[bad[0]]} "
                    f"vs {cb[bad[0]]} (run both with the same --eval.n_episodes and --seed)"
                )
            _pairs(a, b)
    return runs


def records(tasks: dict[int, list[bool]]) -> list[EpisodeRecord]:
    """One suite's episodes as the study's records, keyed by task and index (what pairs them)."""
    return [
        EpisodeRecord(t * TASK_STRIDE + i, ok, "" if ok else "failed", -1, "", 0, math.nan, math.nan)
        for t, successes in sorted(tasks.items())
        for i, ok in enumerate(successes)
    ]


def study_results(runs: list[Run]) -> dict:
    """The study's ``results`` layout: run -> training-seed tag -> suite -> records (tags "0", "1", ...)."""
    return {r.name: {str(k): {s: records(t) for s, t in suites.items()} for k, suites in enumerate(r.suites)}
            for r in runs}  # fmt: skip


def _pairs(a: Run, b: Run) -> list[tuple[int, int]]:
    """Which training seed of ``a`` pairs with which of ``b``: one to one, or each against a run of one."""
    na, nb = len(a.paths), len(b.paths)
    if na == nb:
        return [(k, k) for k in range(na)]
    if na == 1 or nb == 1:
        return [(k if na > 1 else 0, k if nb > 1 else 0) for k in range(max(na, nb))]
    raise ConfigError(
        f"compare: runs {a.name!r} ({na} paths) and {b.name!r} ({nb}) pair neither one to one nor against a run of one"
    )


def paired(results: dict, a: str, b: str, suite_a: str, suite_b: str, pairs: list[tuple[int, int]]) -> dict:
    """``a`` on ``suite_a`` minus ``b`` on ``suite_b`` on the same episodes: the study's per-seed comparisons
    (``results.Comparison``) and the pooled pairs' difference with its 95 % interval."""
    from lerobot_pnp.report.results import Comparison

    comps, cells = [], [0, 0, 0, 0]  # both succeed, a only, b only, neither
    for ka, kb in pairs:
        oa = {r.seed: r.success for r in results[a][str(ka)][suite_a]}
        ob = {r.seed: r.success for r in results[b][str(kb)][suite_b]}
        comps.append(paired_comparison(oa, ob))
        for s in oa.keys() & ob.keys():
            x, y = oa[s], ob[s]
            cells[0 if x and y else 1 if x else 2 if y else 3] += 1
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


def analyse(runs: list[Run], cfg: CompareConfig) -> dict:
    """Every number of the comparison (rates, control arm, pairs of runs, held-out axes) as plain data."""
    from lerobot_pnp.report.results import axis_result, pooled

    results = study_results(runs)
    suites = list(dict.fromkeys(s for r in runs for s in r.suites[0]))
    table = {s: {r.name: p for r in runs if (p := pooled(results[r.name], s))} for s in suites}
    control = {
        r.name: {s: paired(results, r.name, r.name, s, cfg.control, [(k, k) for k in range(len(r.paths))])
                 for s in r.suites[0] if s != cfg.control and cfg.control in r.suites[0]}
        for r in runs
    }  # fmt: skip
    pairs = []
    for i, ref in enumerate(runs):
        for other in runs[i + 1 :]:
            how = _pairs(other, ref)
            for s in (s for s in suites if s in ref.suites[0] and s in other.suites[0]):
                cmp = paired(results, other.name, ref.name, s, s, how)
                pairs.append({"run": other.name, "reference": ref.name, "suite": s, **cmp,
                              "verdict": verdict(cmp, cfg.alpha, cfg.margin)})  # fmt: skip
    seeds = {r.name: {s: seed_agreement(cells[r.name].per_seed) for s, cells in table.items() if r.name in cells}
             for r in runs if len(r.paths) > 1}  # fmt: skip
    axes = [res for axis in HELD_OUT_AXES for r in runs if (res := axis_result(axis, r.name, table))]
    return {"runs": runs, "suites": suites, "table": table, "control": control, "pairs": pairs, "seeds": seeds,
            "axes": axes}  # fmt: skip


def _pts(x: float) -> str:
    return f"{100 * x:+.1f}"


def difference_text(cmp: dict) -> str:
    """A paired difference with its 95 % interval, in points: "+5.2 pts [+1.0, +9.3]"."""
    lo, hi = cmp["interval"]
    return f"{_pts(cmp['difference'])} pts [{_pts(lo)}, {_pts(hi)}]"


def _intro(result: dict, cfg: CompareConfig) -> list[str]:
    lines = ["# Comparison of lerobot-eval runs", ""]
    lines += [
        f"- `{r.name}`: {len(r.paths)} run(s) pooled: " + ", ".join(f"`{p}`" for p in r.paths) for r in result["runs"]
    ]
    if cfg.suites is not None:
        lines.append(f"- suites compared: {cfg.suites} (`--suites`; the runs may hold others)")
    return lines + [
        "",
        "Success with its 95 % Wilson interval (training seeds pooled). Episodes pair by index: episode i of every "
        "suite and run is seed `--seed` + i in lerobot-eval, so the runs must share `--seed` (eval_info.json does "
        f"not record it). Paired tests: exact McNemar per training seed at alpha {cfg.alpha} (improved / regressed: "
        f"every seed's p below it, one direction); held: the 95 % interval of the difference within +-"
        f"{100 * cfg.margin:g} pts; underpowered: neither.",
    ]


def markdown(result: dict, cfg: CompareConfig) -> str:
    """The comparison as markdown: rates per suite, the control arm, pairs of runs, held-out axes."""
    from lerobot_pnp.report.claims import _axis_verdict

    table, names = result["table"], [r.name for r in result["runs"]]
    lines = [*_intro(result, cfg), "", "## Success per suite", ""]
    lines += ["| suite | n | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for s in result["suites"]:
        ns = sorted({table[s][n].rate.n for n in names if n in table[s]})
        cells = [f"{table[s][n].rate}" if n in table[s] else "-" for n in names]
        lines.append(f"| {s} | {'/'.join(map(str, ns))} | " + " | ".join(cells) + " |")
    control = result["control"]
    if any(control.values()):
        lines += ["", f"## Each suite beside the control `{cfg.control}` (same seeds; suite minus control)", ""]
        lines += ["| suite | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
        for s in (s for s in result["suites"] if any(s in control[n] for n in names)):
            lines.append(
                f"| {s} | "
                + " | ".join(difference_text(control[n][s]) if s in control[n] else "-" for n in names)
                + " |"
            )
    if result["pairs"]:
        lines += ["", "## Pairs of runs (run minus reference, same seeds)", ""]
        lines += ["| run | reference | suite | n pairs | difference [95 %] | max p | verdict |", "|---" * 7 + "|"]
        for p in result["pairs"]:
            lines.append(f"| {p['run']} | {p['reference']} | {p['suite']} | {p['n']} | {difference_text(p)} | "
                         f"{p['study'].max_p:.2g} | {p['verdict']} |")  # fmt: skip
    lines += _seeds_markdown(result["seeds"], cfg.alpha)
    if result["axes"]:
        lines += ["", "## Held-out axes (the study's verdict)", ""]
        lines += ["| axis | run | in distribution | held out | verdict |", "|---|---|---|---|---|"]
        for a in result["axes"]:
            lines.append(f"| {a.axis.name} | {a.method} | {a.inside} | {a.outside} | {a.verdict}: {_axis_verdict(a)} |")
    return "\n".join(lines) + "\n"


def _seeds_markdown(seeds: dict, alpha: float) -> list[str]:
    """Per run of several training seeds and suite: do its seeds share one rate (``stats.seed_agreement``)?"""
    if not seeds:
        return []
    lines = ["", "## Do the training seeds agree? (chi-square test of homogeneity)", "",
             f"differ: the seeds' success counts differ beyond evaluation noise (p < {alpha}); the pooled interval "
             "then describes these seeds, not the rate a new training seed gets.", "",
             "| run | suite | per seed | chi2 (dof) | p | seeds |", "|---" * 6 + "|"]  # fmt: skip
    for name, per in seeds.items():
        for suite, a in per.items():
            rates = ", ".join(f"{100 * r.rate:.1f}%" for r in a.per_seed)
            lines.append(f"| {name} | {suite} | {rates} | {a.chi2:.1f} ({a.dof}) | {a.p_value:.2g} | "
                         f"{'differ' if a.differ(alpha) else 'consistent'} |")  # fmt: skip
    return lines


def _diff_json(c: dict) -> dict:
    """The pooled pairs' difference and interval; ``study``: the study's per-seed comparison (mean difference over
    training seeds, the largest p, each seed's test)."""
    return {"n": c["n"], "difference": c["difference"], "interval": list(c["interval"]), "study": c["study"].to_json()}


def to_json(result: dict, cfg: CompareConfig) -> dict:
    """The comparison as JSON (the settings, then the same sections as the markdown)."""
    pairs = [{"run": p["run"], "reference": p["reference"], "suite": p["suite"], **_diff_json(p),
              "verdict": p["verdict"]} for p in result["pairs"]]  # fmt: skip
    return {
        "settings": {"alpha": cfg.alpha, "margin": cfg.margin, "control": cfg.control},
        "runs": {r.name: list(r.paths) for r in result["runs"]},
        "success": {s: {n: p.to_json() for n, p in cells.items()} for s, cells in result["table"].items()},
        "control": {n: {s: _diff_json(c) for s, c in per.items()} for n, per in result["control"].items()},
        "pairs": pairs,
        "seeds": {n: {s: a.to_json(cfg.alpha) for s, a in per.items()} for n, per in result["seeds"].items()},
        "held_out_axes": [a.to_json() for a in result["axes"]],
    }


def run_compare(cfg: CompareConfig) -> dict:
    """Read, check and compare the runs; print the markdown; write compare.md/.json/.png to ``output_dir``.
    Every input is checked and every number computed before anything is written."""
    if not 0 < cfg.alpha < 1 or not 0 <= cfg.margin < 1:
        raise ConfigError(f"compare: alpha must be in (0, 1) and margin in [0, 1), got {cfg.alpha}, {cfg.margin}")
    result = analyse(parse_runs(cfg.runs, cfg.suites), cfg)
    text, data = markdown(result, cfg), to_json(result, cfg)
    print(text)
    if cfg.output_dir is None:
        return {"written": []}
    from lerobot_pnp.report.plots import rate_bars

    out = Path(cfg.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "compare.md").write_text(text)
    (out / "compare.json").write_text(json.dumps(data, indent=2))
    rates = {n: {s: cells[n].rate for s, cells in result["table"].items() if n in cells} for n in data["runs"]}
    seeds = {n: {s: a.per_seed for s, a in per.items()} for n, per in result["seeds"].items()}
    rate_bars(rates, out / "compare.png", "lerobot-pnp compare " + " ".join(cfg.runs), "success per suite", seeds)
    return {"written": [str(out / f) for f in ("compare.md", "compare.json", "compare.png")]}
