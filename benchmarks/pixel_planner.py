"""The camera planner (``pnp_pixels``) measured end to end: data, training, stock evaluation, ``select_action``.

    .venv/bin/python benchmarks/pixel_planner.py [--num_episodes 300] [--epochs 100] [--ckpt_every 25]
        [--n_episodes 100] [--work outputs/pixel_planner] [--out docs/results/pixel_planner.json]

1. Data: ``lerobot-pnp generate`` of the `full` task with ``--cameras`` at ``--size`` (the env's default render
   settings: no shadows, reflections or multisampling), ``--workers`` processes; the generator's own summary
   (wall time, simulation and writing CPU seconds).
2. Training: ``lerobot-pnp train --config_path configs/train_pnp_pixels.json`` (the fast path) for ``--epochs``,
   a checkpoint and a held-out loss every ``--ckpt_every`` epochs; the training's wall time at each checkpoint is
   the loss curve's ``time_s`` (dataset loading and frame decoding before it are in ``train_wall_s``).
3. Each checkpoint: stock ``lerobot-eval`` with no camera flag (the cameras come from the recorded task) on the
   nominal task (the training task unchanged), ``--n_episodes`` seeded episodes from 100000 (the dataset's
   seeds are below); success with its 95 % Wilson interval: success against training time.
4. ``select_action`` at batch 1 of the last checkpoint on pre-rendered observations (joints + the camera image;
   the env's rendering is not in it), mean and median over whole episodes' worth of calls, with and without the
   pre- and post-processors, one torch thread.
5. What the keypoints know: the held-out episodes' environment state predicted by the auxiliary pose head of the
   last checkpoint, mean absolute error per dimension in the state's units (m; sin/cos of 4 x yaw), over every
   frame and over the first frame (nothing in the gripper, nothing hidden).
6. How the last checkpoint fails: its nominal episodes of step 3 again, in process, by cause and furthest phase.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MUJOCO_GL", "egl")

import torch

torch.set_num_threads(1)

REPO = Path(__file__).resolve().parents[1]
PNP = str(Path(sys.executable).parent / "lerobot-pnp")
EVAL_SEED = 100_000
REPO_ID = "local/pixel_planner_full"


def _run(args: list[str]) -> tuple[dict, float]:
    """A ``lerobot-pnp`` command; its printed JSON summary and its wall time."""
    start = time.perf_counter()
    proc = subprocess.run(args, capture_output=True, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(args[:2])} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout[proc.stdout.index("{") :]), wall


def generate(root: Path, episodes: int, workers: int, cameras: str, size: int) -> dict:
    if (root / "meta" / "info.json").is_file():  # reused only where it is the dataset these settings make
        info = json.loads((root / "meta" / "info.json").read_text())
        shapes = {
            k.rsplit(".", 1)[-1]: ft["shape"][:2]
            for k, ft in info["features"].items()
            if k.startswith("observation.images.")
        }
        want = {c: [size, size] for c in cameras.split(",")}
        if info.get("total_episodes") != episodes or shapes != want or not (root.parent / "generate.json").is_file():
            raise SystemExit(
                f"{root} holds a dataset of {info.get('total_episodes')} episodes with cameras {shapes}, not "
                f"{episodes} with {want}: pass another --work"
            )
        return json.loads((root.parent / "generate.json").read_text())
    camera = [f"--env.cameras=[{cameras}]", f"--env.image_height={size}", f"--env.image_width={size}"]
    args = [PNP, "generate", f"--repo_id={REPO_ID}", f"--root={root}", "--seed=0", f"--num_episodes={episodes}"]
    args += [f"--workers={workers}", "--env.preset=full", *camera, "--progress=false"]
    summary, wall = _run(args)
    keep = ("episodes", "frames", "workers", "wall_s", "generate_wall_s", "merge_wall_s", "simulate_cpu_s")
    out = {k: summary.get(k) for k in (*keep, "write_cpu_s")} | {"command_wall_s": round(wall, 1)}
    (root.parent / "generate.json").write_text(json.dumps(out, indent=1))
    return out


def train(root: Path, out: Path, epochs: int, every: int, extra: list[str]) -> dict:
    args = [PNP, "train", f"--config_path={REPO / 'configs' / 'train_pnp_pixels.json'}", *extra]
    args += [f"--dataset_repo_id={REPO_ID}", f"--dataset_root={root}", f"--epochs={epochs}"]
    args += [f"--save_every_epochs={every}", f"--eval_every_epochs={every}", f"--output_dir={out}", "--overwrite=true"]
    summary, wall = _run([*args, "--progress=false"])
    with open(out / "loss_curve.csv") as f:
        curve = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
    return {"summary": summary, "train_wall_s": round(wall, 1), "curve": curve}


def nominal_row(ckpt: Path, out: Path, train_time_s: float, n: int) -> dict:
    """Stock ``lerobot-eval`` of one checkpoint folder (``<step>/pretrained_model`` inside it) on the nominal task,
    ``n`` episodes from ``EVAL_SEED`` into ``out``; its success with the 95 % Wilson interval."""
    from lerobot_pnp.evaluation.stats import wilson_interval
    from lerobot_pnp.report.cli_eval import EvalSpec, run_eval

    res = run_eval(ckpt / "pretrained_model", out, EvalSpec("nominal", n), EVAL_SEED, 50)
    wins = sum(res["per_episode"].values())
    low, high = wilson_interval(wins, n)
    row = {"step": int(ckpt.name), "train_time_s": round(train_time_s, 1), "successes": wins, "n": n,
           "success_pct": round(100 * wins / n, 1), "wilson95_pct": [round(100 * low, 1), round(100 * high, 1)]}  # fmt: skip
    print(row, flush=True)
    return row


def evaluate(out: Path, curve: list[dict], n: int) -> list[dict]:
    """``nominal_row`` of each checkpoint: success against training time."""
    time_at = {int(p["step"]): p["time_s"] for p in curve}
    ckpts = sorted((out / "checkpoints").glob("[0-9]*"), key=lambda p: int(p.name))
    return [nominal_row(c, out / "eval" / c.name, time_at.get(int(c.name), float("nan")), n) for c in ckpts]


def _ms(xs: list[float]) -> dict:
    return {"mean_ms": round(1e3 * statistics.fmean(xs), 3), "median_ms": round(1e3 * statistics.median(xs), 3)}


@torch.inference_mode()
def select_action_cost(ckpt: Path, episodes: int = 20, steps: int = 15) -> dict:
    """ms per ``select_action`` at batch 1 on pre-rendered observations, with and without the processors."""
    from lerobot_pnp.evaluation.checkpoints import load_policy

    loaded = load_policy(ckpt)
    policy = loaded.policy
    images = {k: torch.rand(1, *ft.shape) for k, ft in policy.config.image_features.items()}
    raw = {"observation.state": torch.randn(1, 8), **images, "task": ["pick"]}
    batch = loaded.preprocessor(dict(raw))
    bare, full = [], []
    for times, call in ((bare, lambda: policy.select_action(batch)),
                        (full, lambda: loaded.postprocessor(policy.select_action(loaded.preprocessor(dict(raw)))))):  # fmt: skip
        for _ in range(episodes):
            policy.reset()
            for _ in range(steps):
                t = time.perf_counter()
                call()
                times.append(time.perf_counter() - t)
    params = sum(p.numel() for p in policy.parameters())
    return {"params": params, "b1": _ms(bare[steps:]), "b1_with_processors": _ms(full[steps:])}


@torch.inference_mode()
def pose_error(ckpt: Path, root: Path) -> dict:
    """Mean absolute error of the pose head's environment state on the held-out episodes (unnormalised)."""
    from lerobot_pnp.evaluation.checkpoints import load_policy
    from lerobot_pnp.train_fast.data import load_keyframe_data
    from lerobot_pnp.train_fast.images import episode_images

    loaded = load_policy(ckpt)
    policy = loaded.policy
    if policy.pose_head is None:
        return {}
    ds, data = load_keyframe_data(REPO_ID, root, max_length=policy.config.max_episode_length)
    rows = data.test_idx  # only these episodes' frames are decoded, a few at a time: the dataset's would be GBs
    pad = data.pad[rows]
    counts, episodes, t_max = (~pad).sum(1).numpy(), data.episode_index[rows].numpy(), pad.shape[1]
    parts = []
    for i in range(0, len(rows), 64):
        part = slice(i, i + 64)
        images = {k: episode_images(ds, k, episodes[part], counts[part], t_max) for k in policy.camera_keys}
        parts.append(policy.keypoints({**images, "action_is_pad": pad[part]}))
    feats, real = torch.cat([f for f, _ in parts]), torch.cat([r for _, r in parts])
    stats = ds.meta.stats["observation.environment_state"]
    pred = policy.pose_head(feats) * torch.as_tensor(stats["std"]) + torch.as_tensor(stats["mean"])
    err = (pred - data.env_state[rows]).abs()
    names = ds.meta.features["observation.environment_state"]["names"]
    return {
        "all_frames": {n: round(float(err[real][:, i].mean()), 4) for i, n in enumerate(names)},
        "first_frame": {n: round(float(err[:, 0, i].mean()), 4) for i, n in enumerate(names)},
    }


def failures(ckpt: Path, n: int) -> dict:
    """The last checkpoint's nominal episodes (the seeds of step 3) through ``lerobot-eval``'s own ``eval_policy``
    in this process, which keeps each episode's final info: failures by cause and by furthest FSM phase."""
    from lerobot_pnp.evaluation.checkpoints import load_policy
    from lerobot_pnp.evaluation.closed_loop import eval_lerobot_policy
    from lerobot_pnp.evaluation.records import summarize
    from lerobot_pnp.integration.recorded_task import read_recorded
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    env_cfg = BaxterPnPEnvConfig.from_dict(read_recorded(ckpt) or {})
    loaded = load_policy(ckpt, env_cfg=env_cfg)
    records = eval_lerobot_policy(loaded.policy, loaded.preprocessor, loaded.postprocessor, env_cfg, n, EVAL_SEED, 50)
    return summarize(records)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--num_episodes", type=int, default=300)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--epochs", type=int, default=100)
    parser.add_argument("--ckpt_every", type=int, default=25)
    parser.add_argument("--n_episodes", type=int, default=100)
    parser.add_argument("--cameras", default="front,wrist", help="the cameras recorded and seen, comma-separated")
    parser.add_argument("--size", type=int, default=64, help="image height and width (pixels)")
    parser.add_argument(
        "--train_args", default="", help="more lerobot-pnp train flags, e.g. '--policy.hidden_size=128'"
    )
    parser.add_argument("--work", type=Path, default=REPO / "outputs" / "pixel_planner")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    load = os.getloadavg()[0]
    data = generate(args.work / "data", args.num_episodes, args.workers, args.cameras, args.size)
    print("generate:", data, flush=True)
    run = train(args.work / "data", args.work / "train", args.epochs, args.ckpt_every, args.train_args.split())
    print("train:", run["summary"], f"{run['train_wall_s']} s", flush=True)
    curve = evaluate(args.work / "train", run["curve"], args.n_episodes)
    cost = select_action_cost(args.work / "train" / "checkpoints" / "last" / "pretrained_model")
    print("select_action:", cost, flush=True)
    pose = pose_error(args.work / "train" / "checkpoints" / "last" / "pretrained_model", args.work / "data")
    print("pose error:", pose, flush=True)
    fails = failures(args.work / "train" / "checkpoints" / "last" / "pretrained_model", args.n_episodes)
    print("failures:", fails, flush=True)
    result = {"command": " ".join(["benchmarks/pixel_planner.py", *sys.argv[1:]]), "cpu_count": os.cpu_count(),
              "cameras": args.cameras.split(","), "size": args.size, "train_args": args.train_args,
              "load_before": round(load, 2), "generate": data, "train_wall_s": run["train_wall_s"],
              "train_summary": run["summary"], "loss_curve": run["curve"], "nominal": curve, "select_action": cost, "pose_error": pose, "failures": fails}  # fmt: skip
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
