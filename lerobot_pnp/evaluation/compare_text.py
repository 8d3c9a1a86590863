"""``lerobot-pnp compare``'s result as markdown (``compare.md``, also printed) and as JSON (``compare.json``).

Run names, paths and suite names are the user's text: every one reaches the markdown through
``markdown_text`` (``<script>``, ``|`` or a line break stays literal text in its cell).
"""

from __future__ import annotations

from lerobot_pnp.evaluation.results import axis_phrase
from lerobot_pnp.support.markdown_text import code, text


def _pts(x: float) -> str:
    return f"{100 * x:+.1f}"


def difference_text(cmp: dict) -> str:
    """A paired difference with its 95 % interval, in points: "+5.2 pts [+1.0, +9.3]"."""
    lo, hi = cmp["interval"]
    return f"{_pts(cmp['difference'])} pts [{_pts(lo)}, {_pts(hi)}]"


def _pairing(runs) -> str:
    """How episodes pair, from what the runs record: every file's seeds checked equal, or pairing by index."""
    recorded = [r for r in runs if r.records_seeds]
    if not recorded:
        return (
            "Episodes pair by index: episode i of every suite and run is seed `--seed` + i in lerobot-eval, so the "
            "runs must share `--seed` (eval_info.json does not record it)."
        )
    if len(recorded) == len(runs):
        return "Every run records its episodes' seeds: they are the same in every run, and episodes pair on them."
    others = ", ".join(code(r.name) for r in runs if not r.records_seeds)
    return (
        f"{', '.join(code(r.name) for r in recorded)} record(s) the episodes' seeds, {others} not (a stock "
        "lerobot-eval run records none): episodes pair by index, episode i of every suite being seed `--seed` + i, "
        "so these runs must share the recorded runs' first seed; only the recorded seeds were checked."
    )


def _intro(result: dict, cfg) -> list[str]:
    lines = ["# Comparison of lerobot-eval runs", ""]
    lines += [
        f"- {code(r.name)}: {len(r.paths)} run(s) pooled: " + ", ".join(code(p) for p in r.paths)
        for r in result["runs"]
    ]
    if cfg.suites is not None:
        lines.append(f"- suites compared: {text(cfg.suites)} (`--suites`; the runs may hold others)")
    return lines + [
        "",
        "Success with its 95 % interval, training seeds pooled (several seeds: the interval counts the seeds as well "
        f"as the episodes; one: Wilson's). {_pairing(result['runs'])} Paired tests: "
        f"exact McNemar per training seed at alpha {cfg.alpha} (improved / regressed: every seed's p below it, one "
        f"direction); held: the 95 % interval of the difference within +-{100 * cfg.margin:g} pts; underpowered: "
        "neither.",
    ]


def _row(cells: list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def markdown(result: dict, cfg) -> str:
    """The comparison as markdown: rates per suite, the control arm, pairs of runs, held-out axes (the
    verdict of the one rule, ``verdicts.axis_verdict``, with its difference)."""
    table, names = result["table"], [r.name for r in result["runs"]]
    lines = [*_intro(result, cfg), "", "## Success per suite", ""]
    lines += [_row(["suite", "n", *map(text, names)]), "|---|---|" + "---|" * len(names)]
    for s in result["suites"]:
        ns = sorted({table[s][n].rate.n for n in names if n in table[s]})
        cells = [f"{table[s][n]}" if n in table[s] else "-" for n in names]
        lines.append(_row([text(s), "/".join(map(str, ns)), *cells]))
    control = result["control"]
    if any(control.values()):
        heading = f"## Each suite beside the control {code(result['control_suite'])} (same seeds; suite minus control)"
        lines += ["", heading, ""]
        lines += [_row(["suite", *map(text, names)]), "|---|" + "---|" * len(names)]
        for s in (s for s in result["suites"] if any(s in control[n] for n in names)):
            cells = [difference_text(control[n][s]) if s in control[n] else "-" for n in names]
            lines.append(_row([text(s), *cells]))
    if result["pairs"]:
        lines += ["", "## Pairs of runs (run minus reference, same seeds)", ""]
        lines += ["| run | reference | suite | n pairs | difference [95 %] | max p | verdict |", "|---" * 7 + "|"]
        for p in result["pairs"]:
            lines.append(_row([text(p["run"]), text(p["reference"]), text(p["suite"]), str(p["n"]),
                               difference_text(p), f"{p['study'].max_p:.2g}", p["verdict"]]))  # fmt: skip
    lines += _seeds_markdown(result["seeds"], cfg.alpha)
    if result["axes"]:
        lines += ["", "## Held-out axes (the study's verdict)", ""]
        lines += ["| axis | run | in distribution | held out | verdict |", "|---|---|---|---|---|"]
        for a in result["axes"]:
            lines.append(_row([a.axis.name, text(a.method), str(a.inside), str(a.outside),
                               axis_phrase(a)]))  # fmt: skip
    return "\n".join(lines) + "\n"


def _seeds_markdown(seeds: dict, alpha: float) -> list[str]:
    """Per run of several training seeds and suite: do its seeds share one rate (``stats.seed_agreement``)?"""
    if not seeds:
        return []
    lines = ["", "## Do the training seeds agree? (chi-square test of homogeneity)", "",
             f"differ: the seeds' success counts differ beyond evaluation noise (p < {alpha}); the pooled interval "
             "then widens to their spread.", "",
             "| run | suite | per seed | chi2 (dof) | p | seeds |", "|---" * 6 + "|"]  # fmt: skip
    for name, per in seeds.items():
        for suite, a in per.items():
            rates = ", ".join(f"{100 * r.rate:.1f}%" for r in a.per_seed)
            lines.append(_row([text(name), text(suite), rates, f"{a.chi2:.1f} ({a.dof})", f"{a.p_value:.2g}",
                               "differ" if a.differ(alpha) else "consistent"]))  # fmt: skip
    return lines


def _diff_json(c: dict) -> dict:
    """The pooled pairs' difference and interval; ``study``: the study's per-seed comparison (mean difference over
    training seeds, the largest p, each seed's test)."""
    return {"n": c["n"], "difference": c["difference"], "interval": list(c["interval"]), "study": c["study"].to_json()}


def to_json(result: dict, cfg) -> dict:
    """The comparison as JSON (the settings, then the same sections as the markdown)."""
    pairs = [{"run": p["run"], "reference": p["reference"], "suite": p["suite"], **_diff_json(p),
              "verdict": p["verdict"]} for p in result["pairs"]]  # fmt: skip
    return {
        "settings": {"alpha": cfg.alpha, "margin": cfg.margin, "control": result["control_suite"]},
        "runs": {r.name: list(r.paths) for r in result["runs"]},
        "success": {s: {n: p.to_json() for n, p in cells.items()} for s, cells in result["table"].items()},
        "control": {n: {s: _diff_json(c) for s, c in per.items()} for n, per in result["control"].items()},
        "pairs": pairs,
        "seeds": {n: {s: a.to_json(cfg.alpha) for s, a in per.items()} for n, per in result["seeds"].items()},
        "held_out_axes": [a.to_json() for a in result["axes"]],
    }
