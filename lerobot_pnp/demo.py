"""The end-to-end job (the README's main command): data -> training -> closed-loop evaluation -> report.

1. Generate the paper's dataset: 1400 expert episodes of 10 keyframes, split 80/20 (``lerobot-pnp generate``).
2. Train the paper-faithful two-LSTM planner on the 80 % split with the fast path (``lerobot-pnp train``),
   writing a ``lerobot-train``-layout checkpoint, the loss curves (the paper's Fig. 4) and held-out errors.
3. Evaluate the checkpoint with LeRobot's own ``lerobot-eval`` on unseen object positions, then again with
   the cube nudged before the grasp and noisy observations (the paper's feedback claim).
4. Write ``report.md`` and ``summary.json`` in the output folder.

Every stage is reused when its output already exists (``--fresh=true`` starts over), so an interrupted demo
resumes where it stopped.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from lerobot_pnp.errors import ConfigError, PnPError


@dataclass
class EvalSpec:
    name: str
    n_episodes: int
    env_args: dict[str, float] = field(default_factory=dict)


@dataclass
class DemoConfig:
    output_dir: str = "outputs/demo"
    repo_id: str = "local/baxter_pnp_keyframe"
    num_episodes: int = 1400
    seed: int = 0
    workers: int = 0  # generation worker processes; 0 = one per core
    epochs: int = 300
    batch_size: int = 64
    hidden_size: int = 128
    eval_seed: int = 100_000  # disjoint from the dataset's seeds: unseen object positions
    eval_batch_size: int = 50
    evals: list[EvalSpec] = field(
        default_factory=lambda: [
            EvalSpec("nominal", 500),
            EvalSpec(
                "nudge_3cm_and_noise", 200, {"nudge_max": 0.03, "obs_noise_object": 0.005, "obs_noise_joints": 0.01}
            ),
        ]
    )
    fresh: bool = False

    def __post_init__(self):
        if self.num_episodes < 10:
            raise ConfigError(f"num_episodes must be >= 10 for an 80/20 split, got {self.num_episodes}")
        for spec in self.evals:
            if spec.n_episodes < 1:
                raise ConfigError(f"eval {spec.name!r}: n_episodes must be >= 1")


def _stage(name: str) -> None:
    print(f"\n=== {name} ===", flush=True)


def run_eval(checkpoint: Path, out: Path, spec: EvalSpec, seed: int, batch_size: int) -> dict:
    """``lerobot-eval`` on the env (sync vector envs: the sim is cheap, processes are not). Returns its overall stats."""
    info_path = out / "eval_info.json"
    if not info_path.exists():
        if out.exists():
            shutil.rmtree(out)
        cmd = [
            str(Path(sys.executable).with_name("lerobot-eval")),
            f"--policy.path={checkpoint}",
            "--policy.device=cpu",
            "--env.type=baxter_pnp",
            f"--eval.n_episodes={spec.n_episodes}",
            f"--eval.batch_size={min(batch_size, spec.n_episodes)}",
            "--eval.use_async_envs=false",
            f"--seed={seed}",
            f"--output_dir={out}",
        ] + [f"--env.{k}={v}" for k, v in spec.env_args.items()]
        print(" ".join(cmd), flush=True)
        start = time.perf_counter()
        proc = subprocess.run(cmd, env={**os.environ, "OMP_NUM_THREADS": "1"}, capture_output=True, text=True)
        if proc.returncode != 0 or not info_path.exists():
            raise PnPError(f"lerobot-eval failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
        print(f"  done in {time.perf_counter() - start:.0f} s", flush=True)
    overall = json.loads(info_path.read_text())["overall"]
    return {
        "pc_success": overall["pc_success"],
        "n_episodes": overall.get("n_episodes", spec.n_episodes),
        "env_args": spec.env_args,
        "eval_info": str(info_path),
    }


def run_demo(cfg: DemoConfig) -> dict:
    from lerobot_pnp.dataset import GenerateConfig, generate, validate_dataset
    from lerobot_pnp.policy import PnpLstmConfig
    from lerobot_pnp.train_fast import TrainFastConfig, train_fast

    out = Path(cfg.output_dir)
    if cfg.fresh and out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}

    _stage("1/3 generate expert demonstrations")
    start = time.perf_counter()
    root = out / "dataset"
    try:
        validate_dataset(root)
        print(f"reusing the finished dataset in {root}")
        generation = {"reused": True}
    except PnPError:
        generation = generate(
            GenerateConfig(
                repo_id=cfg.repo_id,
                root=str(root),
                num_episodes=cfg.num_episodes,
                seed=cfg.seed,
                workers=cfg.workers,
                resume=root.exists(),
            )
        )
    timings["generate_s"] = time.perf_counter() - start

    _stage("2/3 train the LSTM task planner (fast path)")
    start = time.perf_counter()
    train_dir = out / "train"
    checkpoint = train_dir / "checkpoints" / "last" / "pretrained_model"
    if checkpoint.exists() and (train_dir / "test_keyframe_error.json").exists():
        print(f"reusing the trained checkpoint {checkpoint}")
    else:
        train_fast(
            TrainFastConfig(
                dataset_repo_id=cfg.repo_id,
                dataset_root=str(root),
                epochs=cfg.epochs,
                batch_size=cfg.batch_size,
                output_dir=str(train_dir),
                overwrite=True,
                policy=PnpLstmConfig(hidden_size=cfg.hidden_size),
            )
        )
    timings["train_s"] = time.perf_counter() - start
    keyframe_error = json.loads((train_dir / "test_keyframe_error.json").read_text())

    _stage("3/3 closed-loop evaluation with lerobot-eval")
    evals = {}
    for spec in cfg.evals:
        start = time.perf_counter()
        evals[spec.name] = run_eval(checkpoint, out / f"eval_{spec.name}", spec, cfg.eval_seed, cfg.eval_batch_size)
        timings[f"eval_{spec.name}_s"] = time.perf_counter() - start
        print(f"  {spec.name}: {evals[spec.name]['pc_success']:.1f}% success over {spec.n_episodes} episodes")

    summary = {
        "config": asdict(cfg),
        "generation": generation,
        "checkpoint": str(checkpoint),
        "held_out_keyframe_error_deg": keyframe_error,
        "evals": evals,
        "timings_s": timings,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str))
    (out / "report.md").write_text(_report(summary, train_dir))
    print(f"\nreport: {out / 'report.md'}")
    return {name: f"{e['pc_success']:.1f}% success" for name, e in evals.items()} | {"report": str(out / "report.md")}


def _report(summary: dict, train_dir: Path) -> str:
    lines = ["# lerobot_pnp demo report", "", "| evaluation | episodes | success |", "|---|---|---|"]
    for name, e in summary["evals"].items():
        lines.append(f"| {name} {e['env_args'] or ''} | {e['n_episodes']} | {e['pc_success']:.1f}% |")
    lines += [
        "",
        f"Loss curves (train vs held-out MSE): `{train_dir / 'loss_curve.png'}`",
        "",
        "Held-out next-keyframe error (degrees):",
        "",
        "```",
        json.dumps(summary["held_out_keyframe_error_deg"], indent=1)[:3000],
        "```",
        "",
        "Stage timings (s): " + ", ".join(f"{k} {v:.0f}" for k, v in summary["timings_s"].items()),
        "",
    ]
    return "\n".join(lines)
