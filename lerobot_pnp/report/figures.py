"""The report's figures, drawn from the evaluation records (``plots`` draws; this picks what to draw).

Each function returns the ``(caption, file name)`` of the figures it wrote under ``layout.figures`` (with the
suites each reads, for ``make_figures`` to name what was left out).
"""

from __future__ import annotations

from lerobot_pnp import robot
from lerobot_pnp.evaluation import plots
from lerobot_pnp.evaluation.results import main_records, pooled
from lerobot_pnp.evaluation.stats import Rate
from lerobot_pnp.evaluation.verdicts import TARGET
from lerobot_pnp.report import adapters, coverage
from lerobot_pnp.report.methods import DATA_EFFICIENCY_METHODS
from lerobot_pnp.sim.suites import HELD_OUT_AXES, SUITES

RECOVERY_FIGURE_SUITES = ("nominal", "slack", "nudge_0.05", "grasp_miss", "drop", "displace")
HEATMAP_SUITES = ("nominal", "nudge_0.03")
FAILURE_SUITES = ("nudge_0.03", "grasp_miss")


def make_figures(layout, cfg, methods, results, suite_names, base_env, prov: str, left=()) -> list[tuple[str, str]]:
    """Every figure the records support, in the report's order. A figure some of whose records were left out
    of the report (``coverage.LeftOut``) is drawn from the rest, its caption naming what it does not draw: what
    was measured still shows, and the figure never passes for the whole comparison."""
    labels = {m.name: m.label for m in methods}
    drawn = [  # (caption, file, the suites it reads, whether it reads the data-efficiency runs)
        *(
            (c + coverage.training_note(left, "clocked_lstm", labels.get("clocked_lstm", "clocked LSTM")), n, (), False)
            for c, n in _loss_figure(layout, cfg, prov)
        ),
        *_heatmaps(layout, cfg, methods, results, suite_names, base_env, prov),
        *_robustness(layout, methods, results, suite_names, prov),
        *((c, n, ("nominal",), True) for c, n in _data_efficiency(layout, cfg, methods, results, prov)),
        *_recovery(layout, methods, results, suite_names, prov),
        *_held_out(layout, methods, results, suite_names, prov),
        *_failures(layout, methods, results, suite_names, prov),
    ]
    return [(c + coverage.figure_note(left, suites, labels, efficiency), n) for c, n, suites, efficiency in drawn]


def _loss_figure(layout, cfg, prov):
    histories = {f"seed {s}": adapters.loss_history(layout.train("clocked_lstm", str(s))) for s in cfg.train_seeds}
    if not any(histories.values()):
        return []
    name = "loss_clocked_lstm.png"
    plots.loss_curves(histories, layout.figure(name), prov)
    return [("Train vs held-out loss of the clocked LSTM (paper Fig. 4)", name)]


def _heatmaps(layout, cfg, methods, results, suite_names, base_env, prov):
    out, first_seed = [], str(cfg.train_seeds[0])
    for suite in [s for s in HEATMAP_SUITES if s in suite_names]:
        panels = {}
        for m in methods:
            tag = "-" if not m.learned else first_seed
            if suite in results.get(m.name, {}).get(tag, {}):
                panels[m.label if tag == "-" else f"{m.label} s{tag}"] = results[m.name][tag][suite]
        name = f"heatmap_{suite}.png"
        out.append((f"Success over the object box, suite `{suite}` (first training seed)", name, (suite,), False))
        plots.success_heatmap(
            panels, base_env.object_low, base_env.object_high, layout.figure(name), prov, title=f"suite {suite}"
        )
    return out


def _robustness(layout, methods, results, suite_names, prov):
    out = []
    for group in sorted({SUITES[s].group for s in suite_names if SUITES[s].group}):
        members = [s for s in suite_names if SUITES[s].group == group]
        curves = {}
        for m in methods:
            pts = [(SUITES[s].x * SUITES[s].x_scale, pooled(results.get(m.name, {}), s)) for s in members]
            if "nominal" in suite_names:
                pts.append((0.0, pooled(results.get(m.name, {}), "nominal")))
            curves[m.label] = [(x, p.rate) for x, p in pts if p]
        name = f"robustness_{group}.png"
        out.append((f"Robustness: {group} sweep (x = 0 is the nominal suite)", name, (*members, "nominal"), False))
        plots.rate_curves(curves, layout.figure(name), prov, SUITES[members[0]].x_label, f"success vs {group}")
    return out


def _data_efficiency(layout, cfg, methods, results, prov):
    if not cfg.data_efficiency:
        return []
    labels, curves = {m.name: m.label for m in methods}, {}
    for m in DATA_EFFICIENCY_METHODS:
        pts = []
        for n in cfg.data_efficiency:
            recs = results.get(m, {}).get(f"n{n}", {}).get("nominal")
            if recs:
                pts.append((float(n), Rate(sum(r.success for r in recs), len(recs))))
        curves[labels.get(m, m)] = pts
    name = "data_efficiency.png"
    plots.rate_curves(curves, layout.figure(name), prov, "training demonstrations", "data efficiency", logx=True)
    return [("Data efficiency: nominal success vs training demonstrations", name)]


def _recovery(layout, methods, results, suite_names, prov):
    recovery = [s for s in RECOVERY_FIGURE_SUITES if s in suite_names]
    if not any(s != "nominal" for s in recovery):  # nominal alone says nothing about corrections
        return []
    rates = {m.label: {s: p.rate for s in recovery if (p := pooled(results.get(m.name, {}), s))} for m in methods}
    plots.rate_bars(
        rates, layout.figure("recovery.png"), prov, "nominal vs disturbances that need a correction or a retry"
    )
    caption = "Success on the suites that need a correction or a retry (all training seeds)"
    return [(caption, "recovery.png", tuple(recovery), False)]


def held_out_panels(suite_names) -> list[tuple[str, list[str], list[str]]]:
    """Per axis of ``HELD_OUT_AXES`` with a held-out suite among ``suite_names``: (axis, its training-condition
    suites, its held-out suites), each kept to the suites evaluated."""
    return [
        (a.name, [s for s in a.in_distribution if s in suite_names], [s for s in a.held_out if s in suite_names])
        for a in HELD_OUT_AXES
        if any(s in suite_names for s in a.held_out)
    ]


def draw_held_out(panels, rates: dict[str, dict[str, Rate]], path, prov: str):
    """The held-out figure (``plots.axis_panels``) with its title and the target line."""
    title = f"trained vs held-out conditions per disturbance axis (dashed: {100 * TARGET:.0f} %)"
    return plots.axis_panels(panels, rates, path, prov, title, target=TARGET)


def _held_out(layout, methods, results, suite_names, prov):
    """The held-out protocol at a glance: per axis of ``HELD_OUT_AXES`` with a held-out suite evaluated, its
    training-condition suites and its held-out ones side by side, every method, against the issue's target."""
    panels = held_out_panels(suite_names)
    if not panels:
        return []
    read = tuple(dict.fromkeys(s for _, inside, held in panels for s in (*inside, *held)))
    rates = {m.label: {s: p.rate for s in read if (p := pooled(results.get(m.name, {}), s))} for m in methods}
    name = "held_out.png"
    draw_held_out(panels, rates, layout.figure(name), prov)
    caption = "Held-out protocol: each axis's training-condition suites, then its held-out ones (all training seeds)"
    return [(caption, name, read, False)]


def failure_suites(methods, results, suite_names) -> list[str]:
    """The suites whose failures are drawn: the paper task's (``FAILURE_SUITES``) when evaluated; else the suite
    other than nominal where the learned method best on nominal fails most (on the `full` task's protocol, where
    the planner's failures are), else the first suite."""
    paper = [s for s in FAILURE_SUITES if s in suite_names]
    if paper:
        return paper
    learned = [
        (p.rate.rate, m.name) for m in methods if m.learned and (p := pooled(results.get(m.name, {}), "nominal"))
    ]
    others = [s for s in suite_names if s != "nominal"]
    if learned and others:
        best = max(learned)[1]
        fails = {s: p.rate.n - p.rate.successes for s in others if (p := pooled(results.get(best, {}), s))}
        if fails and max(fails.values()) > 0:
            return [max(fails, key=fails.get)]
    return suite_names[:1]


def _failures(layout, methods, results, suite_names, prov):
    out = []
    for fail_suite in failure_suites(methods, results, suite_names):
        failures = {}
        for m in methods:
            per: dict[str, dict[str, int]] = {}
            records = main_records(results, m.name, fail_suite)
            for r in records:
                if not r.success:
                    phase = robot.PHASE_NAMES[r.furthest_phase] if r.furthest_phase >= 0 else "unknown"
                    per.setdefault(phase, {}).setdefault(r.failure_cause, 0)
                    per[phase][r.failure_cause] += 1
            if records:  # a method not evaluated on the suite is left out (not "no failures")
                failures[m.label] = per
        name = f"failures_{fail_suite}.png"
        caption = f"Failures by furthest phase and cause, suite `{fail_suite}` (all training seeds)"
        out.append((caption, name, (fail_suite,), False))
        plots.failures_by_phase(failures, layout.figure(name), prov, f"failures, suite {fail_suite}")
    return out
