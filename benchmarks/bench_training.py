"""Training time of the shipped recovering recipe against its target, and against the clocked recipe, in one run.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_training.py [--full_root outputs/ds_full]
        [--paper_root outputs/demo/dataset] [--epochs 300] [--workdir outputs/bench_training]
        [--out outputs/bench_training.json]

The target: training the shipped recovering recipe should still finish in under ``TARGET_S`` on 2 cores. This
times ``train_fast`` as the study trains each method (``report.methods.METHODS[name].train``: the recipe's
policy settings, its batch of ``RECOVERING_BATCH_SIZE`` episodes, the window sized to the recorded task's
keyframe budget) on a keyframe dataset of the ``full`` task at the recipe's budget (1000 demonstrations, 300
epochs, as ``scripts/heldout_protocol_eval.py`` trains it), and the clocked planner's recipe (the paper's,
batch 64) on a keyframe dataset of the ``paper`` task, one after the other in this process (one torch thread
each), so that one machine's load hits both alike. Wall time is from the call to the finished checkpoint
(dataset load and the held-out keyframe error included). The datasets are only read; each training writes
under ``--workdir`` (deleted first).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

ROOT = Path(__file__).resolve().parents[1]
TARGET_S = 15 * 60  # the shipped recovering recipe trains in under 15 minutes on 2 cores


def _time_training(method: str, root: Path, workdir: Path, epochs: int, seed: int) -> dict:
    """Train ``method`` as the study does on ``root``; its wall time and what it trained."""
    from lerobot_pnp.dataset.layout import read_info
    from lerobot_pnp.integration.recorded_task import read_recorded
    from lerobot_pnp.report.methods import TrainContext, get_methods, policy_settings

    (m,) = get_methods([method])
    train_dir = workdir / method
    if train_dir.exists():
        shutil.rmtree(train_dir)
    budget = (read_recorded(root) or {}).get("keyframe_budget")
    ctx = TrainContext(root, train_dir, seed, epochs, task_budget=budget)
    t = time.perf_counter()
    ckpt = m.train(ctx)
    wall = time.perf_counter() - t
    config = json.loads((Path(ckpt) / "config.json").read_text())
    return {
        "method": method,
        "dataset_root": str(root),
        "dataset_episodes": int(read_info(root)["total_episodes"]),
        "task_preset": (read_recorded(root) or {}).get("preset"),
        "epochs": epochs,
        "batch_size": m.batch_size or 64,
        "policy": {k: config.get(k) for k in ("mode", "hidden_size", "num_layers", "max_episode_length", "recurrent")},
        "policy_overrides": policy_settings(m.policy_overrides, ctx),
        "wall_s": round(wall, 1),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--full_root", type=Path, default=ROOT / "outputs" / "ds_full", help="a full-task keyframe dataset")
    p.add_argument("--paper_root", type=Path, default=ROOT / "outputs" / "demo" / "dataset", help="a paper one")
    p.add_argument("--epochs", type=int, default=300)
    p.add_argument("--seed", type=int, default=1000)
    p.add_argument("--workdir", type=Path, default=Path("outputs/bench_training"))
    p.add_argument("--out", type=Path, default=Path("outputs/bench_training.json"))
    args = p.parse_args()
    for flag, root in (("--full_root", args.full_root), ("--paper_root", args.paper_root)):
        if not (root / "meta" / "info.json").is_file():
            p.error(f"{flag} {root} is not a dataset (e.g. lerobot-pnp generate --root {root} --num_episodes 1000)")
    import torch

    from lerobot_pnp.report.provenance import machine

    torch.set_num_threads(1)
    load = os.getloadavg()
    clocked = _time_training("clocked_lstm", args.paper_root, args.workdir, args.epochs, args.seed)
    recovering = _time_training("recovering", args.full_root, args.workdir, args.epochs, args.seed)
    result = {
        "what": "train_fast wall time of the shipped recovering recipe vs the clocked recipe, one after the other",
        "machine": machine(),
        "torch_threads": torch.get_num_threads(),
        "load_average_at_start": [round(v, 2) for v in load],
        "target_s": TARGET_S,
        "recovering": recovering,
        "clocked": clocked,
        "recovering_within_target": recovering["wall_s"] < TARGET_S,
        "ratio_recovering_to_clocked": round(recovering["wall_s"] / clocked["wall_s"], 2),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(
        f"recovering recipe ({recovering['dataset_episodes']} demos, {args.epochs} epochs, batch "
        f"{recovering['batch_size']}): {recovering['wall_s'] / 60:.1f} min (target < {TARGET_S / 60:.0f} min: "
        f"{'met' if result['recovering_within_target'] else 'MISSED'})"
    )
    print(
        f"clocked recipe ({clocked['dataset_episodes']} demos, {args.epochs} epochs, batch {clocked['batch_size']}): "
        f"{clocked['wall_s'] / 60:.1f} min; ratio recovering / clocked: {result['ratio_recovering_to_clocked']:.1f}x"
    )
    print(f"written: {args.out}")


if __name__ == "__main__":
    main()
