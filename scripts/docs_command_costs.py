"""docs/costs.md's tables: what each quick-start command and each make target costs, from the records that measured
them (``docs_tables.py`` renders them; ``--check`` keeps the page equal to the records).

- ``command-costs``: ``docs/results/command_costs.json``, written by ``benchmarks/command_costs.py`` (one machine,
  one run of the README's quick start, each command's wall time, CPU time, peak memory and disk);
- ``make-costs``: ``make install``, ``make test`` and ``make demo`` from ``docs/results/make_costs.json`` (written by
  ``benchmarks/make_costs.py`` from a fresh clone), ``make study`` from the study's own from-scratch cost record
  (``study_cost``, through ``docs_cost``).
"""

from __future__ import annotations

import json
from pathlib import Path

import docs_cost
from docs_cost import duration

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
# the quick start's commands, named as the README's table names them
NAMES = {"generate": "`lerobot-pnp generate`", "train": "`lerobot-pnp train`", "viz": "`lerobot-pnp viz`"}


def _json(rel: str) -> dict:
    return json.loads((RESULTS / rel).read_text())


def size(mb: float | None) -> str:
    """Megabytes as "1.6 GB", "980 MB", "1.1 MB"; None (not measured) as "-"."""
    if mb is None:
        return "-"
    if mb >= 1000:
        return f"{mb / 1024:.1f} GB"
    return f"{mb:.0f} MB" if mb >= 10 else f"{mb:.1f} MB"


def _name(command: str) -> str:
    words = command.split()
    return NAMES.get(words[1], f"`{words[1]}`") if words[0] == "lerobot-pnp" else f"`{words[0]}`"


def _size_flag(command: str) -> str:
    """What the command's size flag asks for, as the quick start sets it ("200 episodes")."""
    words = command.split()
    for flag, unit in (("--num_episodes", "episodes"), ("--epochs", "epochs"), ("--eval.n_episodes", "episodes"),
                       ("--n_episodes", "rollouts")):  # fmt: skip
        if flag in words:
            return f"{words[words.index(flag) + 1]} {unit}"
    return ""


def command_costs(base: str) -> str:
    """The quick start's commands as measured, one row each, and the machine and run that measured them."""
    record = _json("command_costs.json")
    lines = [
        "| command | what | wall time | CPU time | peak memory | disk written |",
        "|---|---|---|---|---|---|",
    ]
    for c in record["commands"]:
        memory = size(c["peak_rss_mb"])
        tree = c.get("peak_tree_rss_mb")
        if tree is not None and tree > 1.2 * c["peak_rss_mb"]:
            memory += f" (its processes together: at most {size(tree)})"
        lines.append(
            f"| {_name(c['command'])} | {_size_flag(c['command'])} | {duration(c['wall_s'])} | "
            f"{duration(c['cpu_s'])} | {memory} | {size(c['disk_mb'])} |"
        )
    m, env = record["machine"], record["environment"]
    settings = ", ".join(f"{k}={v}" for k, v in env.items() if v is not None)
    loads = [c["load_before"] for c in record["commands"]]
    return "\n".join(
        [
            *lines,
            "",
            f"Measured on {m['cpu']}, {m['cores_available']} cores, Python {m['python']}, LeRobot {m['lerobot']}, "
            f"torch {m['torch']}, MuJoCo {m['mujoco']}; {settings}; commit `{m['commit'][:7]}`, {m['date']}; "
            f"the machine's one-minute load before each command: {min(loads):.1f} to {max(loads):.1f} "
            f"(other work shared its cores). Source: `docs/results/command_costs.json` "
            "(`benchmarks/command_costs.py`).",
        ]
    )


def study_cost() -> tuple[str, str, str, str] | None:
    """``make study``'s (time, peak memory, disk, CPU time) from the study's own from-scratch cost record, by the
    rule and in the words of ``docs_cost`` (the one statement of the study's cost); None while the committed
    summaries hold no such record."""
    _, summaries = docs_cost._study()
    cost = docs_cost.measured(summaries)
    if cost is None:
        return None
    return (
        docs_cost._duration(cost["wall_s"]),
        docs_cost._size(cost.get("peak_rss_mb")),
        docs_cost._size(cost.get("disk_mb")),
        "-" if cost.get("cpu_s") is None else duration(cost["cpu_s"]),
    )


def make_costs(base: str) -> str:
    """The make targets: ``make install``, ``make test`` and ``make demo`` as measured one after the other from a
    fresh clone (``docs/results/make_costs.json``), ``make study`` from the study's own from-scratch record."""
    record = _json("make_costs.json")
    lines = [
        "| target | wall time | CPU time | peak memory | disk written | what it ran |",
        "|---|---|---|---|---|---|",
    ]
    ran = {
        "make install": "the venv and the locked dependencies (uv, byte-code compiled)",
        "make test": "ruff, the import layers, the test suite on both cores, the strict docs build",
        "make demo": "the end-to-end job, from empty output folders",
    }
    for target, row in record["targets"].items():
        what = ran.get(target, "")
        if row.get("tests"):
            what += f" ({row['tests'].split(',')[0]}, {'none skipped' if 'skipped' not in row['tests'] else 'some skipped'})"
        lines.append(
            f"| `{target}` | {duration(row['wall_s'])} | {duration(row['cpu_s'])} | {size(row['peak_tree_rss_mb'])} | "
            f"{size(row['disk_mb'])} | {what} |"
        )
    study = study_cost()
    if study is None:
        lines.append(
            "| `make study` | not measured from scratch | - | - | - | the committed study summaries hold no "
            f"from-scratch cost record: their job times replayed, [results, what it costs]({base}index.md#what-it-costs) |"
        )
    else:
        time_, memory, disk, cpu = study
        lines.append(
            f"| `make study` | {time_} | {cpu} | {memory} | {disk} | both studies, from scratch: its own record |"
        )
    m = record["machine"]
    return "\n".join(
        [
            *lines,
            "",
            f"`make install`, `make test` and `make demo`: measured one after the other in a fresh clone by "
            f"`benchmarks/make_costs.py` ({docs_cost._machine(m)}; commit `{m['commit'][:7]}`, {m['date']}; "
            f"SLURM {'up, so its tests ran' if record['slurm'] else 'absent, so its tests skipped'}); peak memory: "
            "the target's processes together, sampled; disk written: what the target added to the clone (the "
            "venv's files are hard links into uv's cache where the file system allows, so the disk they newly "
            "take can be much less). `make study`: `docs/results/study/*/summary.json`, `cost`.",
        ]
    )


def eval_startup(base: str = "") -> str:
    """``lerobot-eval``'s time to its first episode by phase, with this plugin and without it
    (``docs/results/eval_startup.json``, written by ``benchmarks/bench_eval_startup.py``)."""
    rec = _json("eval_startup.json")
    med = rec["median_s"]
    rows = [
        ("LeRobot's imports (torch, the policies, datasets)", "imports"),
        ("plugin discovery", "discovery"),
        ("parsing the command line (every field's help text)", "parse"),
        ("this env (`make_env`)", "make_env"),
        ("the policy and its processors", "make_policy"),
        ("**to the first episode**", "total"),
    ]
    lines = ["| phase | `baxter_pnp` + `pnp_lstm` | a stock config, no plugin |", "|---|---:|---:|"]
    for label, key in rows:
        without = med["without"].get(key)
        right = "-" if key in ("make_env", "make_policy") else f"{without:.2f} s"
        if key == "total":
            right += " (to `make_env`)"
        lines.append(f"| {label} | {med['with'][key]:.2f} s | {right} |")
    ours = sum(rec["plugin_adds_to_stock_s"].values()) + rec["env_and_policy_s"]
    return "\n".join(
        [
            *lines,
            "",
            f"Median of {rec['rounds']} rounds, {rec['cpu']}, {rec['cores']} cores (load average "
            f"{rec['load_average']:.1f}). The plugin's part (discovery and parsing beyond the stock run, the env "
            f"and the policy): {ours:.2f} s, {rec['plugin_share_of_first_episode']:.0%} of the time to the first "
            "episode.",
        ]
    )


BLOCKS = {"command-costs": command_costs, "make-costs": make_costs, "eval-startup": eval_startup}
