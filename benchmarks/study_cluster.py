"""What a study costs as SLURM jobs, and its wall clock on N nodes, replayed from the job times it recorded.

``lerobot-pnp report --executor slurm`` (``report.cluster``) submits each dataset as a job, then each method x
seed's training and suites grouped into cluster jobs (``--slurm.suites_per_job``), a job waiting only on the job
it continues. This script groups a finished study's recorded jobs (its ``summary.json`` ``timings_s``, read as
``study_schedule.py`` reads them) the same way and replays them on ``nodes x cpus_per_node`` one-CPU slots, jobs
started in the order they are submitted once their dependency ended; each cluster job pays ``--startup-s``
(its Python start and imports, measured on the one-node cluster: see ``docs/guides/cluster.md``). The datasets
(``--dataset-s``: their wall seconds measured with ``--dataset-workers`` shard processes) are assumed to scale
with the dataset job's CPUs (``--dataset-cpus``); the ``lerobot-eval`` cross-check runs after, in the submitting
process, as recorded.

    python benchmarks/study_cluster.py --study docs/results/study/report_full/summary.json --dataset-s 624 \\
        --study docs/results/study/heldout/summary.json --dataset-s 403 [--cpus-per-node 32] [--suites-per-job 0]
"""

from __future__ import annotations

import argparse
import heapq
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from study_schedule import summary_jobs

from lerobot_pnp.report.cluster import _waits_on, cluster_tasks


def replay(durations: list[float], waits: list[int | None], slots: int) -> float:
    """Wall time of cluster jobs (``durations``) on ``slots`` CPUs, each started in order once its dependency
    (``waits``) ended and a slot is free."""
    ended: dict[int, float] = {}
    pending, running, clock = list(range(len(durations))), [], 0.0
    while pending or running:
        for i in [i for i in pending if waits[i] is None or waits[i] in ended]:
            if len(running) >= slots:
                break
            pending.remove(i)
            heapq.heappush(running, (clock + durations[i], i))
        clock, i = heapq.heappop(running)
        ended[i] = clock
    return clock


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--study", type=Path, action="append", required=True, help="a finished study's summary.json")
    p.add_argument("--dataset-s", type=float, action="append", default=None, help="its datasets' wall s")
    p.add_argument("--dataset-workers", type=int, default=2, help="shard processes the --dataset-s were measured with")
    p.add_argument("--dataset-cpus", type=int, default=16, help="CPUs of each dataset job (--slurm.dataset_cpus)")
    p.add_argument("--suites-per-job", type=int, default=0)
    p.add_argument("--startup-s", type=float, default=8.0, help="a cluster job's start (Python, imports), s")
    p.add_argument("--cpus-per-node", type=int, default=32)
    p.add_argument("--nodes", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    args = p.parse_args()
    datasets = args.dataset_s or [0.0] * len(args.study)
    jobs, times, serial = [], {}, 0.0
    for i, summary in enumerate(args.study):
        j, t, check, _ = summary_jobs(summary, i)
        jobs, serial = jobs + j, serial + check
        times.update(t)
    tasks = cluster_tasks(jobs, args.suites_per_job)
    durations = [args.startup_s + sum(times[j.key] for j in task) for task in tasks]
    waits = _waits_on(tasks)
    data_wall = sum(d * args.dataset_workers / args.dataset_cpus + args.startup_s for d in datasets)
    cpu_h = (sum(durations) + sum(datasets) * args.dataset_workers) / 3600
    print(
        f"{len(jobs)} study jobs as {len(tasks)} cluster jobs (+ {len(datasets)} dataset jobs of {args.dataset_cpus} "
        f"CPUs); {cpu_h:.2f} CPU-hours, of which {len(tasks) * args.startup_s / 3600:.2f} job starts"
    )
    print("| nodes | CPUs | datasets (s) | train + evaluate (s) | cross-check (s) | total |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: |")
    for nodes in args.nodes:
        slots = nodes * args.cpus_per_node
        pool = replay(durations, waits, slots)
        total = data_wall + pool + serial
        print(f"| {nodes} | {slots} | {data_wall:.0f} | {pool:.0f} | {serial:.0f} | {total / 60:.1f} min |")
    longest = max(durations)
    print(
        f"the longest cluster job: {longest:.0f} s (no number of nodes makes the study shorter than the datasets plus it)"
    )


if __name__ == "__main__":
    main()
