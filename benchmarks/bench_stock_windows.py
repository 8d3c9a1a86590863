"""Stock ``lerobot-train`` data loading for the recovering mode: seconds per step by training-window design.

    .venv/bin/python benchmarks/bench_stock_windows.py --root DATASET [--repo_id ID] [--steps 20] [--rounds 2]

``lerobot-train`` on ``configs/train_pnp_lstm_full.json`` spends almost all its time loading data: every
sample is a window of ``observation_delta_indices`` frames of each ``observation.*`` key and ``action``, and
LeRobot fetches each frame of each window from the dataset. This measures the loader exactly as
``lerobot-train`` builds it (``resolve_delta_timestamps`` from the policy config, ``EpisodeAwareSampler`` with
the config's ``drop_n_last_frames``, ``num_workers=0``, the config's batch size), side by side and interleaved
(A B C A B C, so a shared machine's load hits every design alike), for:

- ``centred``: the shipped recovering config, a window of ``2 * max_episode_length - 1`` frames around any
  frame, so that it holds the sample's whole episode wherever the frame lies;
- ``centred_data``: the same with ``max_episode_length`` set to the dataset's longest episode;
- ``prefix``: ``-(L-1) .. 0``, the frames up to the sampled one (a causal prefix; half the frames);
- ``clocked``: the clocked config of ``configs/train_pnp_lstm.json`` (window 19, batch 8) for reference.

The dataset is any keyframe dataset of the ``full`` task (``lerobot-pnp generate --env.preset full``).
Prints milliseconds per sample and seconds per step of each design, and the time of the shipped number of steps.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

HERE = Path(__file__).resolve().parents[1]


def _policy(config_file: Path, **changes):
    from lerobot_pnp.train_fast import policy_config_from_dict

    data = json.loads(config_file.read_text())
    return policy_config_from_dict({**data["policy"], **changes}), data


def _designs(meta) -> dict[str, tuple[list[int], int, int]]:
    """name -> (delta indices, drop_n_last_frames, batch size)."""
    longest = int(max(meta.episodes["length"]))
    full, full_cfg = _policy(HERE / "configs" / "train_pnp_lstm_full.json")
    data_sized, _ = _policy(HERE / "configs" / "train_pnp_lstm_full.json", max_episode_length=longest)
    clocked, clocked_cfg = _policy(HERE / "configs" / "train_pnp_lstm.json")
    n = full.window_length
    return {
        "centred": (full.observation_delta_indices, full.drop_n_last_frames, full_cfg["batch_size"]),
        "centred_data": (data_sized.observation_delta_indices, 0, full_cfg["batch_size"]),
        "prefix": (list(range(-(n - 1), 1)), 0, full_cfg["batch_size"]),
        "clocked": (clocked.observation_delta_indices, 0, clocked_cfg["batch_size"]),
    }


def _loader(repo_id: str, root: str, deltas: list[int], drop_last: int, batch: int):
    import torch
    from lerobot.datasets import EpisodeAwareSampler
    from lerobot.datasets.lerobot_dataset import LeRobotDataset, LeRobotDatasetMetadata

    meta = LeRobotDatasetMetadata(repo_id, root=root)
    keys = [k for k in meta.features if k.startswith("observation.") or k == "action"]
    ds = LeRobotDataset(repo_id, root=root, delta_timestamps={k: [d / meta.fps for d in deltas] for k in keys})
    sampler = EpisodeAwareSampler(
        ds.meta.episodes["dataset_from_index"],
        ds.meta.episodes["dataset_to_index"],
        drop_n_last_frames=drop_last,
        shuffle=True,
    )
    return torch.utils.data.DataLoader(ds, batch_size=batch, sampler=sampler, num_workers=0, drop_last=True)


def _time_steps(loader, steps: int) -> float:
    it = iter(loader)
    next(it)  # the first batch opens the files
    t0 = time.perf_counter()
    for _ in range(steps):
        try:
            next(it)
        except StopIteration:
            it = iter(loader)
            next(it)
    return (time.perf_counter() - t0) / steps


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--root", required=True, help="a keyframe dataset folder of the full task")
    p.add_argument("--repo_id", default="local/baxter_pnp_full")
    p.add_argument("--steps", type=int, default=20, help="timed batches per design and round")
    p.add_argument("--rounds", type=int, default=2, help="interleaved rounds (A B C A B C)")
    args = p.parse_args(argv)

    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata

    meta = LeRobotDatasetMetadata(args.repo_id, root=args.root)
    lengths = [int(n) for n in meta.episodes["length"]]
    print(f"dataset: {len(lengths)} episodes, mean length {sum(lengths) / len(lengths):.1f}, longest {max(lengths)}")
    designs = _designs(meta)
    loaders = {name: _loader(args.repo_id, args.root, *spec) for name, spec in designs.items()}
    times: dict[str, list[float]] = {name: [] for name in designs}
    for _ in range(args.rounds):
        for name, loader in loaders.items():
            times[name].append(_time_steps(loader, args.steps))
    shipped_steps = json.loads((HERE / "configs" / "train_pnp_lstm_full.json").read_text())["steps"]
    result = {}
    for name, (deltas, _, batch) in designs.items():
        s_step = min(times[name])  # the least loaded round
        result[name] = {"window": len(deltas), "batch": batch, "s_per_step": round(s_step, 4)}
        result[name]["ms_per_sample"] = round(1e3 * s_step / batch, 2)
        print(
            f"{name:<13} window {len(deltas):>3}  batch {batch:>2}  {1e3 * s_step / batch:6.2f} ms/sample  "
            f"{s_step:6.3f} s/step  ({shipped_steps} steps: {s_step * shipped_steps / 60:5.1f} min of loading)"
        )
    print(f"load average: {os.getloadavg()[0]:.2f} (the machine may be shared)")
    return result


if __name__ == "__main__":
    main()
