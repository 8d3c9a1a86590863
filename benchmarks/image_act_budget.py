"""Stock image ACT on the camera planner's data at the camera planner's wall-clock budget.

    .venv/bin/python benchmarks/image_act_budget.py --dataset_root D [--budget_s 1800] [--save_freq 200]
        [--n_episodes 100] [--threads 1] [--work outputs/image_act_budget]
        [--out docs/results/pixel_baselines/image_act.json]

1. Training: stock ``lerobot-train`` of ACT (ResNet-18 from scratch, the ``configs/train_act_images.json``
   architecture) on the dataset's joints and every camera it records (no object or goal coordinates), on
   ``--threads`` torch threads (the camera planner's recipe trains on two), a checkpoint every ``--save_freq``
   steps. ACT's optimiser has no schedule, so stopping it at the budget is the same run as one planned for that
   many steps: the process is stopped at the first checkpoint past ``--budget_s`` of training (timed from
   LeRobot's "Start offline training" line, so dataset loading is not in it, as it is not in the camera planner's
   loss-curve times).
2. The last checkpoint within each quarter of the budget: stock ``lerobot-eval`` on the nominal task,
   ``--n_episodes`` seeded episodes from 100000, success with its 95 % Wilson interval, and the training time at which it was written.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MUJOCO_GL", "egl")

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
EVAL_SEED = 100_000
ACT_FLAGS = json.loads((REPO / "configs" / "train_act_images.json").read_text())["policy"]


def act_flags(root: Path) -> list[str]:
    """ACT's flags: the shipped image-ACT architecture, with the dataset's joints and all of its cameras as inputs."""
    info = json.loads((root / "meta" / "info.json").read_text())
    inputs = {"observation.state": {"type": "STATE", "shape": info["features"]["observation.state"]["shape"]}}
    for key, ft in info["features"].items():
        if key.startswith("observation.images."):
            h, w, c = ft["shape"]
            inputs[key] = {"type": "VISUAL", "shape": [c, h, w]}
    flags = [f"--policy.input_features={json.dumps(inputs)}"]
    for key, value in ACT_FLAGS.items():
        if key != "input_features":
            flags.append(f"--policy.{key}={'null' if value is None else json.dumps(value).strip(chr(34))}")
    return flags


def train(root: Path, repo_id: str, out: Path, budget_s: float, save_freq: int, seed: int, threads: int) -> dict:
    """Stock ``lerobot-train`` until the first checkpoint past the budget; each checkpoint's training time."""
    cmd = [str(BIN / "lerobot-train"), f"--dataset.repo_id={repo_id}", f"--dataset.root={root}",
           "--dataset.video_backend=pyav", *act_flags(root), f"--seed={seed}", "--num_workers=0", "--batch_size=16",
           "--steps=1000000", f"--save_freq={save_freq}", "--log_freq=50", "--env_eval_freq=0", f"--output_dir={out}"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "OMP_NUM_THREADS": str(threads)})  # fmt: skip
    started: list[float] = []
    log = open(out.parent / "train.log", "w")  # noqa: SIM115 (written by the reader thread, closed below)

    def read() -> None:
        for line in proc.stdout:
            log.write(line)
            log.flush()
            if "Start offline training" in line and not started:
                started.append(time.perf_counter())

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    seen: dict[int, float] = {}
    while proc.poll() is None:
        time.sleep(1.0)
        for ckpt in (out / "checkpoints").glob("[0-9]*"):
            if int(ckpt.name) not in seen and (ckpt / "pretrained_model" / "model.safetensors").is_file():
                seen[int(ckpt.name)] = round(time.perf_counter() - started[0], 1)
                print(f"checkpoint {ckpt.name} at {seen[int(ckpt.name)]} s", flush=True)
        if seen and max(seen.values()) >= budget_s:
            time.sleep(5.0)  # the checkpoint's files are complete when the training step after it has begun
            proc.terminate()
            proc.wait()
    reader.join(timeout=10)
    log.close()
    if not seen:
        raise SystemExit(f"lerobot-train wrote no checkpoint; see {out.parent / 'train.log'}")
    return {"command": " ".join(cmd), "checkpoint_time_s": {str(k): v for k, v in sorted(seen.items())}}


def evaluate(out: Path, times: dict[str, float], n: int, budget_s: float) -> list[dict]:
    """``pixel_planner.nominal_row`` of the last checkpoint within each quarter of the budget: success against
    training time."""
    from pixel_planner import nominal_row

    picked = {
        max((s for s, t in times.items() if t <= q * budget_s), default=None, key=int) for q in (0.25, 0.5, 0.75, 1)
    }
    folders = {int(p.name): p for p in (out / "checkpoints").glob("[0-9]*")}
    steps = sorted(int(s) for s in picked if s is not None)
    return [nominal_row(folders[s], out.parent / "eval" / str(s), times[str(s)], n) for s in steps]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dataset_root", type=Path, required=True)
    parser.add_argument("--repo_id", default="local/pixel_planner_full")
    parser.add_argument("--budget_s", type=float, default=1800.0)
    parser.add_argument("--save_freq", type=int, default=200)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--n_episodes", type=int, default=100)
    parser.add_argument("--threads", type=int, default=1, help="torch threads of the training (OMP_NUM_THREADS)")
    parser.add_argument("--work", type=Path, default=REPO / "outputs" / "image_act_budget")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    run = train(
        args.dataset_root, args.repo_id, args.work / "train", args.budget_s, args.save_freq, args.seed, args.threads
    )
    rows = evaluate(args.work / "train", run["checkpoint_time_s"], args.n_episodes, args.budget_s)
    result = {"command": " ".join(["benchmarks/image_act_budget.py", *sys.argv[1:]]), "cpu_count": os.cpu_count(),
              "budget_s": args.budget_s, "threads": args.threads, "train": run, "nominal": rows}  # fmt: skip
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
