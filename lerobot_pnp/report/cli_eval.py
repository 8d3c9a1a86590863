"""The real ``lerobot-eval`` command line, as a subprocess: the cross-check of the in-process evaluation.

``evaluation.py`` calls the same ``eval_policy`` in process (to record each episode's final info); this
module runs the CLI itself on the same seeds, so the report can show that both give the same successes.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from lerobot_pnp.errors import PnPError


@dataclass
class EvalSpec:
    name: str
    n_episodes: int
    env_args: dict[str, float] = field(default_factory=dict)


def run_eval(checkpoint: Path, out: Path, spec: EvalSpec, seed: int, batch_size: int) -> dict:
    """``lerobot-eval`` on the env (sync vector envs: the sim is cheap, processes are not). Returns its overall
    stats and the per-episode successes (``{seed: success}``)."""
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
    info = json.loads(info_path.read_text())
    overall = info["overall"]
    # one task here: its successes are in seed order, seed + i (eval_policy's start_seed numbering)
    successes = [ok for task in info.get("per_task", []) for ok in task["metrics"]["successes"]]
    per_episode = {seed + i: bool(ok) for i, ok in enumerate(successes[: spec.n_episodes])}
    return {
        "pc_success": overall["pc_success"],
        "n_episodes": overall.get("n_episodes", spec.n_episodes),
        "env_args": spec.env_args,
        "eval_info": str(info_path),
        "per_episode": per_episode,
    }
