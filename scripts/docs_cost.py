"""The docs' statements of what `make demo` and `make study` cost (the ``cost`` and ``study-cost`` blocks of
``docs_tables.py``).

`make demo`'s cost comes from ``docs/results/make_costs.json``: ``benchmarks/make_costs.py`` runs it (after `make
install` and `make test`) in a fresh clone and measures it.

The study's cost comes from its own record: the ``cost`` block that a run writes into every study's
``summary.json`` (``lerobot_pnp.report.cost``). A record counts as the study's cost only when that run did every
stage itself (``from_scratch``); a resumed run's wall clock is not. Where the committed summaries hold no such
record, the blocks say so and give what the summaries do hold instead: their recorded job times replayed
through the study's pool (``benchmarks/study_schedule.py``), labelled as a replay, with what it leaves out. Every
page that states the study's cost takes this one value.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
STAGES = {  # cost.STAGES -> what the table calls it
    "datasets": "datasets (expert demonstrations and their recordings)",
    "jobs": "trainings, evaluations and `lerobot-eval` cross-checks (one pool)",
    "cli_check": "the cross-checks' comparison (after the pool)",
    "report": "reports and figures",
}


def _json(rel: str) -> dict:
    return json.loads((RESULTS / rel).read_text())


def _duration(seconds: float) -> str:
    minutes = round(seconds / 60)
    return f"{minutes} min" if minutes < 60 else f"{minutes // 60} h {minutes % 60:02d} min"


def _size(mb: float | None) -> str:
    return "-" if mb is None else f"{mb / 1024:.1f} GB" if mb >= 1024 else f"{mb:.0f} MB"


def _machine(m: dict) -> str:
    return f"{m['cpu']}, {m['cores_available']} cores; LeRobot {m['lerobot']}, torch {m['torch']}, MuJoCo {m['mujoco']}"


def _study() -> tuple[dict, list[dict]]:
    src = _json("sources.json")["study"]
    return src, [_json(f) for f in src["files"]]


def _provenance(src: dict, summary: dict) -> str:
    m = summary["machine"]
    commit = (m.get("commit") or src["commit"])[:7]
    return f"commit `{commit}`, {m.get('date', src['date'])}"


def measured(summaries: list[dict]) -> dict | None:
    """The study's own from-scratch cost record, or None: the first summary's ``cost`` when its run did every
    stage itself."""
    cost = summaries[0].get("cost")
    return cost if isinstance(cost, dict) and cost.get("from_scratch") else None


def replayed(src: dict) -> dict:
    """The committed summaries' job times replayed through the study's pool on 2 processes (``study_schedule``)."""
    spec = importlib.util.spec_from_file_location("study_schedule", ROOT / "benchmarks" / "study_schedule.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench.replay_studies([RESULTS / f for f in src["files"]], processes=2)


def study_line() -> str:
    """The one statement of `make study`'s cost."""
    src, summaries = _study()
    machine, where = _machine(summaries[0]["machine"]), _provenance(src, summaries[0])
    if (cost := measured(summaries)) is not None:
        return (
            f"- `make study`: **{_duration(cost['wall_s'])}** from scratch on {machine}, measured by the study "
            f"itself (`cost` in its `summary.json`; peak memory {_size(cost['peak_rss_mb'])}, "
            f"{_size(cost['disk_mb'])} on disk; {where})."
        )
    r = replayed(src)
    return (
        "- `make study`: **not yet measured from scratch** by the study's own record: the committed summaries come "
        f"from a run that reused its datasets. Their job times ({_duration(r['train_s'])} of training, "
        f"{_duration(r['eval_s'])} of evaluation) replay to {_duration(r['pool_s'] + r['serial_s'])} on 2 processes "
        "for the trainings, evaluations and cross-checks alone (`benchmarks/study_schedule.py`; datasets and "
        f"reports not included); {machine}, {where}."
    )


def make_target(target: str) -> tuple[dict, dict]:
    """``make <target>``'s measurement from a fresh clone and the machine and commit that measured it
    (``docs/results/make_costs.json``, written by ``benchmarks/make_costs.py``)."""
    record = _json("make_costs.json")
    return record["targets"][f"make {target}"], record["machine"]


def duration(seconds: float) -> str:
    """``seconds`` as a reader reads a duration: "14 s", "3 min 5 s", "1 h 12 min"."""
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60} s"
    return f"{s // 3600} h {s % 3600 // 60} min"


def demo_line() -> str:
    """The one statement of `make demo`'s cost."""
    demo, m = make_target("demo")
    return (
        f"- `make demo`: **{duration(demo['wall_s'])}** from a fresh clone, the venv installed, on "
        f"{_machine(m)} (`benchmarks/make_costs.py`; commit `{m['commit'][:7]}`, {m['date']})."
    )


def cost_lines(base: str) -> str:
    """What `make demo` and `make study` cost, on the machine that measured them."""
    return demo_line() + "\n" + study_line()


def cost_table(base: str) -> str:
    """`make study` stage by stage, from its record; the replay's parts where there is no record."""
    src, summaries = _study()
    lines = ["| stage | wall clock | cores busy | peak memory | disk at its end |", "|---|---:|---:|---:|---:|"]
    if (cost := measured(summaries)) is None:
        r = replayed(src)
        return "\n".join([
            "| stage | recorded job time | wall clock on 2 processes (replayed) |", "|---|---:|---:|",
            "| datasets | not recorded (reused) | not recorded |",
            f"| trainings | {_duration(r['train_s'])} | |",
            f"| evaluations and `lerobot-eval` cross-checks | {_duration(r['eval_s'])} | |",
            f"| both, side by side in one pool | {_duration(r['train_s'] + r['eval_s'])} | {_duration(r['pool_s'])} |",
            "| reports and figures | not recorded | not recorded |",
            "",
            "Replayed from the job times of the committed summaries (no run recorded from scratch yet); "
            + _provenance(src, summaries[0]) + ".",
        ])  # fmt: skip
    for name, s in cost["stages"].items():
        busy = "-" if s["cpu_s"] is None or not s["wall_s"] else f"{s['cpu_s'] / s['wall_s']:.1f}"
        lines.append(f"| {STAGES.get(name, name)} | {_duration(s['wall_s'])} | {busy} | {_size(s['peak_rss_mb'])} | "
                     f"{_size(s['disk_mb'])} |")  # fmt: skip
    busy = "-" if cost["cpu_s"] is None else f"{cost['cpu_s'] / cost['wall_s']:.1f}"
    lines.append(f"| **whole run** | **{_duration(cost['wall_s'])}** | {busy} | {_size(cost['peak_rss_mb'])} | "
                 f"{_size(cost['disk_mb'])} |")  # fmt: skip
    ran = ", ".join(f"{what.replace('cli_checks', 'cross-checks')} {done}" for what, (done, _) in cost["ran"].items())
    return "\n".join([
        *lines,
        "",
        f"Measured by the study itself from scratch ({ran}, every one made by this run), {cost['processes']} "
        f"processes; cores busy: CPU seconds of every process per second; peak memory: {cost['memory_how']}; the "
        f"largest job process {_size(cost['job_rss_mb'])}. {_machine(summaries[0]['machine'])}, "
        + _provenance(src, summaries[0]) + ".",
    ])  # fmt: skip


BLOCKS = {"cost": cost_lines, "study-cost": cost_table}
