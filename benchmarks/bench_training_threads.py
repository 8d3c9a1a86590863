"""Whether a study training gives the same weights at 2 torch threads as at 1, and how much faster it is.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_training_threads.py --workdir outputs/bench_threads
        [--task paper] [--num_episodes 100] [--epochs 20] [--act_steps 60] [--methods clocked_lstm recovering act]

The study trains every job on one thread (``job.run_job``). A training that runs alone while the pool's other
core waits on it could use 2 threads, but only if that leaves its weights bit-identical: the study's results must
not depend on which job happened to run alone. This benchmark generates a small dataset of ``--task`` (the
recordings the methods need, under ``--workdir``, reused when there), trains each method as the study does
(``report.methods.METHODS[name].train``, the recipe's batch) once at 1 thread and once at 2, each in a fresh
process, and prints the wall times and whether every saved weight is equal (the largest difference when not).
Timings need an otherwise idle machine; the equality does not.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
METHODS = ["clocked_lstm", "recovering", "memoryless_mlp", "phase_told_mlp", "act"]


def _cfg(args):
    from lerobot_pnp.report.config import StudyConfig

    return StudyConfig(output_dir=str(args.workdir), preset="quick", num_episodes=args.num_episodes, workers=1,
                       epochs=args.epochs, act_steps=args.act_steps, methods=args.methods, task_preset=args.task)  # fmt: skip


def prepare(args) -> None:
    """The recordings the methods train on, keyed as the study keys them (reused when already made)."""
    from lerobot_pnp.report.run import RECORDINGS
    from lerobot_pnp.report.stages import dataset_stage

    cfg, keys = _cfg(args), {}
    _, keys["keyframe"] = dataset_stage(args.workdir, "dataset", cfg)
    for data, (_, changes) in RECORDINGS.items():
        _, keys[data] = dataset_stage(args.workdir, f"dataset_{data}", cfg, changes)
    (args.workdir / "keys.json").write_text(json.dumps(keys))


def train(args, method: str, threads: int) -> float:
    """``method`` trained as the study trains it, at ``threads`` torch threads; its wall seconds."""
    import torch

    from lerobot_pnp.integration.recorded_task import read_recorded
    from lerobot_pnp.report.methods import TrainContext, get_methods

    pin = torch.set_num_threads
    pin(threads)
    # the trainers pin their own count (``support.determinism.deterministic_training``, 1 as the study runs them):
    # here every call pins the count this run measures
    torch.set_num_threads = lambda _n: pin(threads)
    (m,) = get_methods([method])
    cfg, root = _cfg(args), args.workdir
    roots = {"keyframe": root / "dataset", "dense": root / "dataset_dense", "phase": root / "dataset_phase"}
    budget = (read_recorded(roots["keyframe"]) or {}).get("keyframe_budget")
    ctx = TrainContext(roots["keyframe"] if m.data == "dense" else roots[m.data], root / f"threads{threads}" / method,
                       1000, cfg.epochs, None, roots["dense"], cfg.act_steps, json.loads((root / "keys.json").read_text()),
                       budget, dict(cfg.recipe_changes))  # fmt: skip
    t = time.perf_counter()
    m.train(ctx)
    return time.perf_counter() - t


def same_weights(workdir: Path, method: str) -> str:
    """ "identical" when every weight file of the two trainings is equal, else the largest difference."""
    import torch
    from safetensors.torch import load_file

    files = [sorted((workdir / f"threads{t}" / method).rglob("model.safetensors")) for t in (1, 2)]
    if not files[0] or len(files[0]) != len(files[1]):
        return "no weights to compare"
    worst = 0.0
    for a, b in zip(*files, strict=True):
        wa, wb = load_file(a), load_file(b)
        for k in wa:
            if not torch.equal(wa[k], wb[k]):
                worst = max(worst, float((wa[k].double() - wb[k].double()).abs().max()))
    return "identical" if worst == 0.0 else f"differ (largest {worst:.3g})"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--workdir", type=Path, required=True)
    p.add_argument("--task", default="paper", choices=["paper", "full"])
    p.add_argument("--num_episodes", type=int, default=100)
    p.add_argument("--epochs", type=int, default=20)
    p.add_argument("--act_steps", type=int, default=60)
    p.add_argument("--methods", nargs="+", default=METHODS)
    p.add_argument("--train", nargs=2, metavar=("METHOD", "THREADS"), help=argparse.SUPPRESS)  # one child run
    args = p.parse_args()
    if args.train:
        print(json.dumps({"wall_s": train(args, args.train[0], int(args.train[1]))}))
        return
    prepare(args)
    print("| method | 1 thread (s) | 2 threads (s) | weights |\n|---|---:|---:|---|")
    for method in args.methods:
        walls = []
        for threads in (1, 2):
            out = subprocess.run([sys.executable, __file__, *sys.argv[1:], "--train", method, str(threads)],
                                 check=True, capture_output=True, text=True).stdout  # fmt: skip
            walls.append(json.loads(out.strip().splitlines()[-1])["wall_s"])
        print(f"| {method} | {walls[0]:.1f} | {walls[1]:.1f} | {same_weights(args.workdir, method)} |", flush=True)


if __name__ == "__main__":
    main()
