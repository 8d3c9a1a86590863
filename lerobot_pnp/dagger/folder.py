"""DAgger's output folder, through the one owner of output folders (``lerobot_pnp.outputs``).

A run records every top-level entry it will write (``demos``, ``round_NN``, ``table.md``/``table.json``,
``summary.json``) in the folder's manifest before any work, so an entry of the user's with one of those names
(a dataset called ``demos``, a ``round_05`` folder) is refused in one line with nothing written, and only
recorded entries are ever replaced or deleted (the rounds beyond ``--rounds`` left by an earlier run). A folder a
DAgger run wrote before the manifest existed is recognised by the stage records only DAgger writes there, and
its entries are recorded as DAgger's (``legacy_entries``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from lerobot_pnp.evaluation.stats import Rate
from lerobot_pnp.outputs import OutputFolder, read_record

COMMAND = "lerobot-pnp dagger"
ROUND = re.compile(r"round_(\d{2,})")
TABLE_FILES = ("table.md", "table.json")
SUMMARY_FILE = "summary.json"
# The stage records a DAgger run writes in an entry (path inside it, the record's stage), which no other
# command writes: what proves a folder from before the manifest is DAgger's.
DEMOS_RECORDS = (("stage.json", "demos"),)
ROUND_RECORDS = (("rollouts.json", "rollouts"), ("data/stage.json", "aggregate"), ("train/done.json", "train"),
                 ("eval.stage.json", "eval"))  # fmt: skip


def round_name(rnd: int) -> str:
    return f"round_{rnd:02d}"


def _stage_of(path: Path) -> str | None:
    """The ``stage`` part of the record at ``path`` (never read through a link); None when it is not one."""
    data = read_record(path)
    parts = data.get("parts") if isinstance(data, dict) else None
    return parts.get("stage") if isinstance(parts, dict) else None


def _recorded(entry: Path, records: tuple[tuple[str, str], ...]) -> bool:
    return entry.is_dir() and not entry.is_symlink() and any(_stage_of(entry / p) == s for p, s in records)


def _is_table(path: Path) -> bool:
    """A ``table.json``/``summary.json`` as ``write_table``/``run_dagger`` write them."""
    data = read_record(path)
    if path.name == SUMMARY_FILE:
        return isinstance(data, dict) and {"final_checkpoint", "timings_s", "table"} <= set(data)
    return isinstance(data, list) and all(isinstance(row, dict) and "policy" in row for row in data)


def legacy_entries(folder: OutputFolder) -> list[str]:
    """The entries of a DAgger folder written before the manifest: ``demos`` and the ``round_NN`` folders that
    hold DAgger's stage records (and the empty ``round_NN`` beside them), its table and summary. None where
    DAgger already recorded entries, or where no record of DAgger's is found."""
    if folder.entries:
        return []
    path = folder.path
    found = ["demos"] if _recorded(path / "demos", DEMOS_RECORDS) else []
    rounds = [p for p in path.iterdir() if ROUND.fullmatch(p.name) and p.is_dir() and not p.is_symlink()]
    found += [p.name for p in rounds if _recorded(p, ROUND_RECORDS)]
    if not found:
        return []
    found += [p.name for p in rounds if p.name not in found and not any(p.iterdir())]
    if _is_table(path / "table.json") or _is_table(path / SUMMARY_FILE):
        found += [n for n in (*TABLE_FILES, SUMMARY_FILE) if (path / n).is_file() and not (path / n).is_symlink()]
    return found


def claim_run(folder: OutputFolder, cfg) -> None:
    """Record every entry the run of ``cfg`` (a ``DaggerConfig``) writes, before any work; refuse (one line,
    nothing recorded) an entry of that name that is not DAgger's."""
    if legacy := legacy_entries(folder):
        folder.adopt(*legacy)
    names = ([] if cfg.base_root else ["demos"]) + [round_name(r) for r in range(cfg.rounds + 1)]
    names += [*TABLE_FILES, SUMMARY_FILE] if cfg.n_episodes > 0 else [SUMMARY_FILE]
    folder.claim(*names)


def remove_later_rounds(folder: OutputFolder, rounds: int) -> None:
    """DAgger's rounds beyond ``rounds``, left by an earlier run with more rounds, would sit beside this run's
    table: deleted. A ``round_NN`` DAgger did not write is left where it is."""
    for entry in sorted(folder.path.iterdir()):
        match = ROUND.fullmatch(entry.name)
        if match and int(match[1]) > rounds and folder.owns(entry.name):
            folder.remove(entry.name)


def write_table(rows: list[tuple[str, dict]], suites: list[str], out: Path | OutputFolder) -> str:
    """Markdown table: one row per policy, success and Wilson 95 % interval per suite; ``table.md`` and
    ``table.json`` written together into ``out`` (a folder path, or the run's held ``OutputFolder``)."""
    lines = ["| policy | " + " | ".join(suites) + " |", "|---" * (len(suites) + 1) + "|"]
    data = []
    for name, res in rows:
        rates = {s: Rate(res[s]["successes"], res[s]["n"]) for s in suites if s in res}
        cells = [str(rates[s]) if s in rates else "-" for s in suites]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
        data.append(
            {"policy": name, **{s: {**res[s], "rate": r.rate, "wilson95": r.interval} for s, r in rates.items()}}
        )
    table = "\n".join(lines) + "\n"
    files = {"table.md": table.encode(), "table.json": json.dumps(data, indent=2).encode()}
    if isinstance(out, OutputFolder):
        out.write_set(files)
    else:
        with OutputFolder(out, COMMAND) as folder:
            folder.write_set(files)
    return table
