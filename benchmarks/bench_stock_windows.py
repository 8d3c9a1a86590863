"""Stock ``lerobot-train`` for the recovering mode: seconds per training step by design, side by side.

    .venv/bin/python benchmarks/bench_stock_windows.py --root DATASET [--repo_id ID] [--steps 20] [--rounds 2]

Every sample of the recovering config is a window of ``observation_delta_indices`` frames of each
``observation.*`` key and ``action`` that holds the sample's whole episode. LeRobot's map-style
``LeRobotDataset`` fetches each frame of each window from the Arrow table (a fixed cost per sample plus a cost
per window frame: the old config spent almost all its step there), while its ``StreamingLeRobotDataset``
(``--dataset.streaming=true``) reads the files in order once and cuts the windows out of an in-memory buffer.
This times one training step as ``lerobot-train`` runs it (the loader built as it builds it: the config's
delta timestamps (the recovering designs' phase labels windowed too, as the plugin's ``stock_train`` does), ``EpisodeAwareSampler`` with the policy's ``drop_n_last_frames`` for a map-style dataset, a
stream with ``max_num_shards=num_workers`` otherwise, the config's ``num_workers``; then the pre-processor,
forward, backward, gradient clipping, Adam and the scheduler), interleaved (A B C A B C, so a shared machine's
load hits every design alike), for:

- ``old``: the recovering config as shipped before (map-style, window ``2 * 41 - 1`` frames, batch 32, 3000
  steps, no workers);
- ``sized``: ``old`` with the window sized to the data (``max_episode_length`` of the new config), map-style;
- ``new``: ``configs/train_pnp_lstm_full.json`` as shipped now (streaming, the sized window, one worker);
- ``clocked``: ``configs/train_pnp_lstm.json`` (map-style, window 19, batch 8), the speed to match.

The dataset is any keyframe dataset of the ``full`` task (the recovering config's own, e.g.). Prints seconds per
step, the ratios to ``old`` and ``clocked``, and each design's run time (its steps times its seconds per step). ``--lerobot_train N`` then also runs the
stock CLI itself for ``N`` steps per design (one after the other; ``--clocked_root``: a paper keyframe dataset
for the clocked config) and reports the seconds per step LeRobot logs.
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
FULL_CONFIG = HERE / "configs" / "train_pnp_lstm_full.json"
CLOCKED_CONFIG = HERE / "configs" / "train_pnp_lstm.json"
# The recovering config before this benchmark's change (what `old` times): the top-level and policy fields.
OLD_RECOVERING = {
    "batch_size": 32,
    "steps": 3000,
    "num_workers": 0,
    "dataset": {"streaming": False},
    "policy": {"max_episode_length": 41, "scheduler_warmup_steps": 200},
}


def _design(config_file: Path, changes: dict | None = None) -> dict:
    """A config file's training setup with ``changes`` applied: policy config, loader and run length."""
    from lerobot_pnp.train_fast import policy_config_from_dict

    data = json.loads(config_file.read_text())
    changes = changes or {}
    policy = policy_config_from_dict({**data["policy"], **changes.get("policy", {})})
    return {
        "policy": policy,
        "deltas": policy.observation_delta_indices,
        "streaming": bool({**data["dataset"], **changes.get("dataset", {})}.get("streaming", False)),
        "num_workers": changes.get("num_workers", data.get("num_workers", 0)),
        "batch": changes.get("batch_size", data["batch_size"]),
        "steps": changes.get("steps", data["steps"]),
    }


def _designs() -> dict[str, dict]:
    sized = {**OLD_RECOVERING, "policy": {**OLD_RECOVERING["policy"]}}
    del sized["policy"]["max_episode_length"]  # the new config's
    return {
        "old": _design(FULL_CONFIG, OLD_RECOVERING),
        "sized": _design(FULL_CONFIG, sized),
        "new": _design(FULL_CONFIG),
        "clocked": _design(CLOCKED_CONFIG),
    }


def _loader(repo_id: str, root: str, spec: dict):
    """The training loader ``lerobot-train`` builds for this design (``make_dataset`` and its ``DataLoader``)."""
    import torch
    from lerobot.datasets import EpisodeAwareSampler
    from lerobot.datasets.lerobot_dataset import LeRobotDataset, LeRobotDatasetMetadata
    from lerobot.datasets.streaming_dataset import StreamingLeRobotDataset

    from lerobot_pnp.integration.stock_train import phase_windows, stream_labels_as_arrays

    meta = LeRobotDatasetMetadata(repo_id, root=root)
    keys = [k for k in meta.features if k.startswith("observation.") or k == "action"]
    delta_timestamps = {k: [d / meta.fps for d in spec["deltas"]] for k in keys}
    delta_timestamps = phase_windows(spec["policy"], meta, delta_timestamps)  # as the plugin does in lerobot-train
    batch, workers = spec["batch"], spec["num_workers"]
    if spec["streaming"]:
        ds = StreamingLeRobotDataset(
            repo_id, root=root, delta_timestamps=delta_timestamps, max_num_shards=workers, return_uint8=True
        )
        stream_labels_as_arrays(ds)
        return torch.utils.data.DataLoader(ds, batch_size=batch, num_workers=workers, drop_last=True), meta
    ds = LeRobotDataset(repo_id, root=root, delta_timestamps=delta_timestamps)
    sampler = EpisodeAwareSampler(
        ds.meta.episodes["dataset_from_index"],
        ds.meta.episodes["dataset_to_index"],
        drop_n_last_frames=spec["policy"].drop_n_last_frames,
        shuffle=True,
    )
    loader = torch.utils.data.DataLoader(ds, batch_size=batch, sampler=sampler, num_workers=workers, drop_last=True)
    return loader, meta


def _trainer(repo_id: str, root: str, spec: dict):
    """(loader, one-step function) as ``lerobot-train`` builds them for this design."""
    import torch
    from lerobot.policies.factory import make_pre_post_processors
    from lerobot.utils.feature_utils import dataset_to_policy_features

    from lerobot_pnp.integration.stock_train import labels_kept
    from lerobot_pnp.policy import PnpLstmPolicy

    loader, meta = _loader(repo_id, root, spec)
    cfg = spec["policy"]
    features = dataset_to_policy_features(meta.features)
    cfg.output_features = {k: f for k, f in features.items() if k == "action"}
    cfg.input_features = {k: f for k, f in features.items() if k.startswith("observation.")}
    policy = PnpLstmPolicy(cfg)  # no dataset_meta: the clocked design reads a dataset of other lengths
    policy.train()
    preprocessor, _ = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    if cfg.recovering:  # the phase labels reach the policy, as in lerobot-train with the plugin
        preprocessor.to_transition = labels_kept(preprocessor.to_transition)
    optimizer = cfg.get_optimizer_preset().build(policy.get_optim_params())
    sched_cfg = cfg.get_scheduler_preset()
    scheduler = sched_cfg.build(optimizer, spec["steps"]) if sched_cfg is not None else None

    def step(batch: dict) -> None:
        loss, _ = policy.forward(preprocessor(batch))
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), cfg.optimizer_grad_clip_norm)
        optimizer.step()
        optimizer.zero_grad()
        if scheduler is not None:
            scheduler.step()

    return loader, step


def _time_steps(loader, step, steps: int) -> tuple[float, float]:
    """(seconds per step, of which loading) over ``steps`` steps after a first untimed one."""
    it = iter(loader)

    def batch():
        nonlocal it
        try:
            return next(it)
        except StopIteration:
            it = iter(loader)
            return next(it)

    step(batch())  # the first batch opens the files
    load = 0.0
    t0 = time.perf_counter()
    for _ in range(steps):
        t1 = time.perf_counter()
        b = batch()
        load += time.perf_counter() - t1
        step(b)
    return (time.perf_counter() - t0) / steps, load / steps


def _flags(changes: dict, prefix: str = "") -> list[str]:
    """``{"policy": {"x": 1}, "steps": 2}`` -> ``["--policy.x=1", "--steps=2"]`` (draccus' command line)."""
    out = []
    for key, value in changes.items():
        if isinstance(value, dict):
            out += _flags(value, f"{prefix}{key}.")
        else:
            out.append(f"--{prefix}{key}={str(value).lower() if isinstance(value, bool) else value}")
    return out


def _cli_designs() -> dict[str, tuple[Path, list[str]]]:
    """Each design as (config file, flags) of the stock CLI (run length and dataset root set by the caller)."""
    old = {k: v for k, v in OLD_RECOVERING.items() if k != "steps"}
    sized = {**old, "policy": {k: v for k, v in old["policy"].items() if k != "max_episode_length"}}
    return {
        "old": (FULL_CONFIG, _flags(old)),
        "sized": (FULL_CONFIG, _flags(sized)),
        "new": (FULL_CONFIG, []),
        "clocked": (CLOCKED_CONFIG, ["--env_eval_freq=0"]),
    }


def _lerobot_train(name: str, root: str, steps: int, out: Path) -> dict:
    """Stock ``lerobot-train`` for ``steps`` steps; s/step from its last log line (the second half of the run:
    ``update_s`` + ``dataloading_s``, averaged by LeRobot over the ``log_freq`` steps before it)."""
    import re
    import shutil
    import subprocess
    import sys

    config, flags = _cli_designs()[name]
    shutil.rmtree(out, ignore_errors=True)
    cmd = [str(Path(sys.executable).with_name("lerobot-train")), f"--config_path={config}", *flags]
    cmd += [f"--dataset.root={root}", f"--steps={steps}", f"--log_freq={steps // 2}", f"--save_freq={steps}"]
    cmd += [f"--output_dir={out}"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
    wall = time.perf_counter() - t0
    lines = re.findall(r"updt_s:([0-9.]+) data_s:([0-9.]+)", proc.stdout + proc.stderr)
    if proc.returncode != 0 or not lines:
        raise SystemExit(f"lerobot-train {name} failed ({proc.returncode}): {(proc.stdout + proc.stderr)[-2000:]}")
    update, data = (float(v) for v in lines[-1])
    return {"s_per_step": round(update + data, 4), "s_loading_per_step": data, "wall_s": round(wall, 1)}


def _with_ratios(rows: dict[str, dict]) -> dict[str, dict]:
    """Each design's step and run time as ratios to the old and the clocked design (added in place)."""
    for row in rows.values():
        row["step_ratio_to_old"] = round(row["s_per_step"] / rows["old"]["s_per_step"], 3)
        row["step_ratio_to_clocked"] = round(row["s_per_step"] / rows["clocked"]["s_per_step"], 3)
        row["run_ratio_to_clocked"] = round(row["run_min"] / rows["clocked"]["run_min"], 3)
    return rows


def _report_cli(designs: dict[str, dict], rows: dict[str, dict]) -> dict:
    for name, row in rows.items():
        row["steps"] = designs[name]["steps"]
        row["run_min"] = round(row["s_per_step"] * row["steps"] / 60, 2)
    for name, row in _with_ratios(rows).items():
        print(
            f"lerobot-train {name:<8} {row['s_per_step']:6.3f} s/step ({row['s_loading_per_step']:.3f} loading)  "
            f"x{row['step_ratio_to_old']:.3f} of old, x{row['step_ratio_to_clocked']:.2f} of clocked  "
            f"{row['steps']} steps: {row['run_min']:5.1f} min (x{row['run_ratio_to_clocked']:.2f} of clocked)"
        )
    return rows


def _report(designs: dict[str, dict], times: dict[str, list[tuple[float, float]]]) -> dict:
    result = {}
    for name, spec in designs.items():
        s_step, s_load = min(times[name])  # the least loaded round
        result[name] = {
            "window": len(spec["deltas"]),
            "streaming": spec["streaming"],
            "batch": spec["batch"],
            "steps": spec["steps"],
            "s_per_step": round(s_step, 4),
            "s_loading_per_step": round(s_load, 4),
            "ms_loading_per_sample": round(1e3 * s_load / spec["batch"], 2),
            "run_min": round(s_step * spec["steps"] / 60, 2),
        }
    for name, row in _with_ratios(result).items():
        print(
            f"{name:<8} {'stream' if row['streaming'] else 'map   '} window {row['window']:>3}  batch {row['batch']:>2}  {row['ms_loading_per_sample']:6.2f} ms "
            f"loading/sample  {row['s_per_step']:6.3f} s/step ({row['s_loading_per_step']:.3f} loading)  "
            f"x{row['step_ratio_to_old']:.3f} of old, x{row['step_ratio_to_clocked']:.2f} of clocked  "
            f"{row['steps']} steps: {row['run_min']:5.1f} min (x{row['run_ratio_to_clocked']:.2f} of clocked)"
        )
    return result


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--root", required=True, help="a keyframe dataset folder of the full task")
    p.add_argument("--repo_id", default="local/baxter_pnp_full_demos")
    p.add_argument("--steps", type=int, default=20, help="timed steps per design and round")
    p.add_argument("--rounds", type=int, default=2, help="interleaved rounds (A B C A B C)")
    p.add_argument(
        "--lerobot_train", type=int, default=0, help="also run stock lerobot-train this many steps per design"
    )
    p.add_argument("--clocked_root", default=None, help="a paper keyframe dataset for the clocked lerobot-train run")
    p.add_argument("--output", type=Path, default=None, help="write the results as JSON here")
    args = p.parse_args(argv)

    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata

    meta = LeRobotDatasetMetadata(args.repo_id, root=args.root)
    lengths = [int(n) for n in meta.episodes["length"]]
    print(f"dataset: {len(lengths)} episodes, mean length {sum(lengths) / len(lengths):.1f}, longest {max(lengths)}")
    designs = _designs()
    trainers = {name: _trainer(args.repo_id, args.root, spec) for name, spec in designs.items()}
    times: dict[str, list[tuple[float, float]]] = {name: [] for name in designs}
    load_before = os.getloadavg()[0]
    for _ in range(args.rounds):
        for name, (loader, step) in trainers.items():
            times[name].append(_time_steps(loader, step, args.steps))
    result = _report(designs, times)
    if args.lerobot_train:
        if args.clocked_root is None:
            raise SystemExit("--lerobot_train needs --clocked_root (a paper keyframe dataset for the clocked config)")
        out = Path(args.output or "outputs/bench_stock_windows.json").with_suffix("")
        rows = {}
        for name in _cli_designs():
            root = args.clocked_root if name == "clocked" else args.root
            rows[name] = _lerobot_train(name, root, args.lerobot_train, out / name)
            print(f"lerobot-train {name}: {rows[name]}", flush=True)
        result["lerobot_train"] = _report_cli(designs, rows)
    load = (load_before, os.getloadavg()[0])
    print(f"load average (1 min) before / after: {load[0]:.2f} / {load[1]:.2f} (the machine may be shared)")
    result["load_average"] = load
    if args.output is not None:
        args.output.parent.mkdir(parents=True, exist_ok=True)
        args.output.write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
