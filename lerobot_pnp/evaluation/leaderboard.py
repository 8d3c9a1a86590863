"""``lerobot-pnp leaderboard``: the leaderboard page, generated from committed stock ``eval_info.json`` outputs.

Each row is a folder of ``runs_dir`` holding the ``eval_info.json`` of one stock ``lerobot-eval --env.task
heldout`` run (or several, one per training seed, in sub-folders) and ``row.json``: ``label`` (what the method is)
and ``command`` (the ``lerobot-eval`` command that produced it), optionally ``name`` (a short name for compact
tables, the README's) and ``budget`` (its data, training and time, in a few words). The page shows, per row, the
budget, the rate on ``nominal``,
each axis' in-distribution and held-out rates with the study's verdict, and per suite the rate with its 95 %
interval: ``compare``'s numbers (the study's code), so a row means the same as in ``compare`` and in the study.
Every row is checked against the others (same suites, same episodes per suite), or the page is not written.
"""

from __future__ import annotations

import json
import posixpath
from dataclasses import dataclass
from pathlib import Path

from lerobot_pnp.errors import ConfigError

ADD_ROW = (
    "lerobot-eval --policy.path <checkpoint> --env.type baxter_pnp --env.task heldout --eval.n_episodes {episodes} "
    "--eval.batch_size 50 --policy.device cpu --seed {seed} --output_dir {runs_dir}/<name>"
)


ROW_KEYS = {"label", "command", "name", "budget"}  # row.json: label and command required, name and budget optional


@dataclass
class LeaderboardConfig:
    """``lerobot-pnp leaderboard``: regenerate the page from the rows under ``runs_dir``."""

    runs_dir: str = "docs/results/leaderboard"  # one folder per row: eval_info.json (or one per seed) + row.json
    output: str = "docs/leaderboard.md"  # the generated page
    episodes: int = 100  # episodes per suite of every row (and of the command that adds one)
    seed: int = 100_000  # lerobot-eval --seed of every row: the study's first evaluation seed
    check: bool = False  # write nothing; exit 2 unless the page is what the rows give (for CI)


def _rows(runs_dir: Path) -> list[tuple[str, dict, list[str]]]:
    """(name, row.json, eval_info folders) per row folder, in name order."""
    if not runs_dir.is_dir():
        raise ConfigError(f"leaderboard: no folder {runs_dir}")
    rows = []
    for folder in sorted(p for p in runs_dir.iterdir() if p.is_dir()):
        meta_file = folder / "row.json"
        if not meta_file.is_file():
            raise ConfigError(f"leaderboard: {folder} has no row.json (label, command)")
        meta = json.loads(meta_file.read_text())
        if not isinstance(meta, dict) or not {"label", "command"} <= set(meta):
            raise ConfigError(f"leaderboard: {meta_file} must hold a label and a command")
        unknown = sorted(set(meta) - ROW_KEYS)
        if unknown:
            raise ConfigError(f"leaderboard: {meta_file}: unknown key {unknown[0]!r}; valid: {sorted(ROW_KEYS)}")
        not_text = [k for k in sorted(meta) if not isinstance(meta[k], str)]
        if not_text:
            raise ConfigError(f"leaderboard: {meta_file}: {not_text[0]!r} must be text, not {meta[not_text[0]]!r}")
        runs = [str(folder)] if (folder / "eval_info.json").is_file() else sorted(
            str(p.parent) for p in folder.glob("*/eval_info.json"))  # fmt: skip
        if not runs:
            raise ConfigError(f"leaderboard: {folder} holds no eval_info.json")
        rows.append((folder.name, meta, runs))
    if not rows:
        raise ConfigError(f"leaderboard: {runs_dir} holds no row")
    return rows


def analyse_rows(runs_dir: str | Path, episodes: int = 100) -> tuple[list[tuple[str, dict]], dict, dict]:
    """Every row under ``runs_dir`` read, checked and analysed with ``compare``'s code: ((name, row.json) per row,
    ``compare.analyse``'s result, {(axis name, row name): its held-out verdict}); the page and the README's
    table (scripts/docs_tables.py) both read their numbers from here."""
    from lerobot_pnp.evaluation.compare import CompareConfig, analyse, parse_runs

    rows = _rows(Path(runs_dir))
    specs = [f"{name}={','.join(runs)}" for name, _, runs in rows]
    runs = parse_runs(specs)
    short = sorted(
        {f"{r.name}: {s}" for r in runs for s, t in r.suites[0].items() if sum(map(len, t.values())) != episodes}
    )
    if short:
        raise ConfigError(f"leaderboard: every suite needs {episodes} episodes; {short[0]} has another count")
    result = analyse(runs, CompareConfig(runs=specs))
    axes = {(a.axis.name, a.method): a for a in result["axes"]}
    return [(name, meta) for name, meta, _ in rows], result, axes


def render(runs_dir: str | Path, episodes: int = 100, seed: int = 100_000) -> str:
    """The page for the rows under ``runs_dir`` (the same text for the same files); every suite of every row holds
    ``episodes`` episodes."""
    from lerobot_pnp.evaluation.suites import HELD_OUT_AXES

    rows, result, axes = analyse_rows(runs_dir, episodes)
    table = result["table"]
    lines = [
        "# Leaderboard: the held-out protocol",
        "",
        "Generated by `lerobot-pnp leaderboard` from the stock `lerobot-eval` outputs under "
        f"`{runs_dir}` (do not edit by hand). Success with its 95 % Wilson interval, training seeds pooled; per axis"
        " of [the held-out protocol](benchmark/heldout.md) the in-distribution and held-out rates and the study's "
        "verdict. To add a row, evaluate a checkpoint on the whole protocol, add a `row.json` (`label`, `command`; "
        "optionally a short `name` and its `budget`) beside its `eval_info.json`, and regenerate the page:",
        "",
        "```bash",
        ADD_ROW.format(runs_dir=runs_dir, episodes=episodes, seed=seed),
        f"lerobot-pnp leaderboard --runs_dir {runs_dir} --output docs/leaderboard.md",
        "```",
        "",
        "The lookup table is a checkpoint like the others (`lerobot-pnp lookup-table` writes it from a dataset's "
        "training episodes). The expert is privileged (it reads the simulator), so it is no policy of observations "
        "and no checkpoint: its row is `lerobot-pnp expert --env.task heldout`, which runs the same suites, env "
        "configs and seeds as `lerobot-eval` and writes `lerobot-eval`'s `eval_info.json` layout. Each row's "
        "commands are at the end of the page.",
        "",
        "| row | method | budget | nominal | " + " | ".join(a.name for a in HELD_OUT_AXES) + " |",
        "|---|---|---|---|" + "---|" * len(HELD_OUT_AXES),
    ]
    for name, meta in rows:
        cells = [_axis_cell(axes.get((a.name, name))) for a in HELD_OUT_AXES]
        nominal = table.get("nominal", {}).get(name)
        lines.append(
            f"| `{name}` | {meta['label']} | {meta.get('budget', '-')} | {nominal.rate if nominal else '-'} | "
            + " | ".join(cells)
            + " |"
        )
    lines += ["", "## Per suite", "", "| suite | " + " | ".join(f"`{n}`" for n, _ in rows) + " |"]
    lines.append("|---|" + "---|" * len(rows))
    for suite in result["suites"]:
        lines.append(
            f"| {suite} | "
            + " | ".join(str(table[suite][n].rate) if n in table[suite] else "-" for n, _ in rows)
            + " |"
        )
    lines += ["", "## How each row was produced", ""]
    lines += [f"- `{name}`: `{meta['command']}`" for name, meta in rows]
    return "\n".join(lines) + "\n"


AXIS_MARK = {"generalises": "✓", "degrades": "≈", "fails": "✗", "no_recovery": "○"}
NBSP = "\N{NO-BREAK SPACE}"  # inside a compact table's cell, so a narrow column does not split it


def _pct(x: float) -> str:
    return f"{100 * x:.1f}".removesuffix(".0")


def compact_table(runs_dir: str | Path, episodes: int = 100, leave_out: tuple[str, ...] = ()) -> tuple[str, list[str]]:
    """(One line per row, strongest first: short name, budget, nominal % with its 95 % interval, held-out % per axis
    with the verdict as ``AXIS_MARK``'s symbol; the short names of the rows in ``leave_out``): the README's table,
    the page's numbers."""
    from lerobot_pnp.evaluation.suites import HELD_OUT_AXES

    rows, result, axes = analyse_rows(runs_dir, episodes)
    nominal = result["table"]["nominal"]
    held = {n: [axes.get((a.name, n)) for a in HELD_OUT_AXES] for n, _ in rows}  # None: the row lacks the axis
    shown = [(n, m) for n, m in rows if n not in leave_out]
    shown.sort(key=lambda r: (-nominal[r[0]].rate.rate, -sum(a.outside.rate for a in held[r[0]] if a)))
    lines = ["| method | budget | nominal | " + " | ".join(a.name for a in HELD_OUT_AXES) + " |"]
    lines.append("|---" * (len(HELD_OUT_AXES) + 3) + "|")
    for n, meta in shown:
        rate = nominal[n].rate
        lo, hi = rate.interval
        cells = [f"{_pct(rate.rate)}{NBSP}[{_pct(lo)},{NBSP}{_pct(hi)}]"]
        cells += [f"{_pct(a.outside.rate)}{NBSP}{AXIS_MARK[a.verdict]}" if a else "-" for a in held[n]]
        lines.append(f"| {meta.get('name', n)} | {meta.get('budget', '-')} | " + " | ".join(cells) + " |")
    return "\n".join(lines), [m.get("name", n) for n, m in rows if n in leave_out]


def readme_block(root: Path, docs: str, leave_out: tuple[str, ...] = ()) -> str:
    """The README's leaderboard: ``compact_table`` of the default rows under ``root``, its legend (links relative
    to ``docs``, the docs folder seen from the page) and the commands that add a row."""
    from lerobot_pnp.report.results import TARGET

    cfg = LeaderboardConfig()
    table, left_out = compact_table(root / cfg.runs_dir, cfg.episodes, leave_out)
    heldout, page = (posixpath.normpath(docs + rel) for rel in ("benchmark/heldout.md", Path(cfg.output).name))
    legend = (
        f"Success %: on `nominal` with its 95 % interval, and per axis of [the held-out protocol]({heldout}) "
        "the held-out rate with the verdict: ✓ generalises, ≈ only partly, ✗ does not, ○ no verdict (below "
        f"{100 * TARGET:.0f} % in distribution already). Budget: data, training, seeds and training time on 2 CPU "
        'cores, CPU time where measured, else wall time ("(study)": the study\'s training wall time). One '
        f"stock `lerobot-eval --env.task heldout` per row, {cfg.episodes} episodes per suite from seed {cfg.seed:,}; "
        "ACT counts latency in 20 fps steps, not keyframes. "
        + "".join(f"Left out: the floor, {f}. " for f in left_out)
        + f"Every suite and each row's commands: [the leaderboard]({page}). To add a row:"
    )
    add = ADD_ROW.format(runs_dir=cfg.runs_dir, episodes=cfg.episodes, seed=cfg.seed)
    add = add.replace(" --eval.batch_size", " \\\n  --eval.batch_size", 1)
    cmd = f"lerobot-pnp leaderboard   # rewrites {cfg.output}; then python scripts/docs_tables.py"
    return "\n".join([table, "", legend, "", "```bash", add, cmd, "```"])


def _axis_cell(result) -> str:
    if result is None:
        return "-"
    return f"{100 * result.inside.rate:.1f} -> {100 * result.outside.rate:.1f}: {result.verdict}"


def write_leaderboard(cfg: LeaderboardConfig) -> dict:
    """Regenerate the page (every row read and checked first; nothing written on failure), or with ``check`` say
    whether the committed page is what the rows give."""
    text = render(cfg.runs_dir, cfg.episodes, cfg.seed)
    if cfg.check:
        page = Path(cfg.output)
        if not page.is_file() or page.read_text() != text:
            raise ConfigError(
                f"leaderboard: {cfg.output} is not what {cfg.runs_dir} gives; run lerobot-pnp leaderboard"
            )
        return {"up_to_date": cfg.output}
    Path(cfg.output).write_text(text)
    return {"written": cfg.output}
