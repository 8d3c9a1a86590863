"""A study's measured cost against the replay of its own job times, side by side, so that the replay stays honest.

    python benchmarks/study_cost.py --study outputs/report_full/summary.json --study outputs/heldout/summary.json
    python benchmarks/study_cost.py --run configs/report_full.json --run configs/report_heldout.json --out runs/cost

The study records its own cost: the ``cost`` block of each ``summary.json`` (``lerobot_pnp.report.cost``). With
``--run`` this benchmark first runs the study from scratch, the first config with the others alongside it (as
``make study`` does: about an hour and a half on 2 cores), each into a new folder under ``--out`` (which must not
exist yet, so that nothing is reused), then reads what it recorded. It replays that run's job times through the
study's pool (``study_schedule.replay_studies``, on the record's processes) and prints, part by part, what the run
measured beside what the replay gives; the stages the replay does not model (the datasets, the comparison of the
cross-checks after the pool, the reports) count as measured in both. The pool's measured wall clock exceeds the
replay by what no job times: starting the pool and each job, reading its inputs, building its envs.

Exit 1 when the record is not from scratch (a resumed run's wall clock is not the study's cost; ``--allow-resumed``
shows it anyway) or when the pool's measured wall clock and its replay differ by more than ``--tolerance``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from study_schedule import replay_studies


def run_from_scratch(configs: list[Path], out: Path) -> list[Path]:
    """``lerobot-pnp report`` on ``configs`` (the first with the others alongside), each writing into a new
    folder ``out/<config name>``; the summaries it wrote."""
    if out.exists():
        raise SystemExit(f"--out {out} exists: give a new folder, so that the study reuses nothing")
    out.mkdir(parents=True)
    paths = []
    for config in configs:
        data = {**json.loads(config.read_text()), "output_dir": str(out / config.stem)}
        paths.append(out / config.name)
        paths[-1].write_text(json.dumps(data, indent=2))
    cmd = [str(Path(sys.executable).with_name("lerobot-pnp")), "report", "--config_path", str(paths[0])]
    for other in paths[1:]:
        cmd += ["--alongside", str(other)]
    print(" ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)
    return [out / config.stem / "summary.json" for config in configs]


def compare(summaries: list[Path]) -> tuple[list[tuple[str, float, float | None]], dict]:
    """(part, measured seconds, replayed seconds) for each part of the run, and its cost record."""
    cost = json.loads(summaries[0].read_text()).get("cost")
    if not isinstance(cost, dict):
        raise SystemExit(f"{summaries[0]} holds no cost record (written by a study run before the study recorded one)")
    stages = {name: s["wall_s"] for name, s in cost["stages"].items()}
    r = replay_studies(summaries, processes=cost["processes"])
    outside = stages.get("datasets", 0.0) + stages.get("cli_check", 0.0) + stages.get("report", 0.0)
    rows = [
        ("datasets", stages.get("datasets", 0.0), None),
        (f"trainings and evaluations: one pool of {cost['processes']}", stages.get("jobs", 0.0), r["pool_s"]),
        ("cross-checks left after the pool", stages.get("cli_check", 0.0), r["serial_s"]),
        ("reports and figures", stages.get("report", 0.0), None),
        ("whole run", cost["wall_s"], outside - stages.get("cli_check", 0.0) + r["pool_s"] + r["serial_s"]),
    ]
    return rows, {**cost, "job_s": r["train_s"] + r["eval_s"]}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--study", type=Path, action="append", default=[], help="a study's summary.json (of one run)")
    p.add_argument("--run", type=Path, action="append", default=[], help="a study config to run from scratch first")
    p.add_argument("--out", type=Path, default=Path("outputs/study_cost"), help="a new folder for --run")
    p.add_argument("--tolerance", type=float, default=0.10, help="largest relative gap of the pool and its replay")
    p.add_argument("--allow-resumed", action="store_true", help="compare a run that reused stages too")
    args = p.parse_args()
    summaries = run_from_scratch(args.run, args.out) if args.run else args.study
    if not summaries:
        raise SystemExit("give --study (a summary.json of a run) or --run (a study config)")
    rows, cost = compare(summaries)
    print("| part | measured (s) | replayed (s) | measured / replayed |\n|---|---:|---:|---:|")
    for part, measured, replayed in rows:
        ratio = f"{measured / replayed:.2f}" if replayed else "-"
        print(f"| {part} | {measured:.0f} | {'-' if replayed is None else f'{replayed:.0f}'} | {ratio} |")
    pool, replayed = rows[1][1], rows[1][2]
    print(f"job time {cost['job_s']:.0f} s; peak memory {cost['peak_rss_mb']:.0f} MB; disk {cost['disk_mb']:.0f} MB; "
          f"from scratch: {cost['from_scratch']} (done by this run / in the study: {cost['ran']})")  # fmt: skip
    if not cost["from_scratch"] and not args.allow_resumed:
        print("not a from-scratch run: its wall clock is not the study's cost (--allow-resumed to compare anyway)")
        return 1
    if replayed and abs(pool / replayed - 1) > args.tolerance:
        print(f"the pool's wall clock and its replay differ by more than {args.tolerance:.0%}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
