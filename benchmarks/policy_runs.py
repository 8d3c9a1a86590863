"""What the policy benchmarks share (``bench_policy.py``): training on the fast path, finding its checkpoints,
and closed-loop success in process or through the real ``lerobot-eval``."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

EVAL_SEED = 100_000


def log(msg: str) -> None:
    print(msg, flush=True)


# ---------------------------------------------------------------------------------------------- helpers
_ENVS: dict = {}


def _env(env_args: dict):
    from lerobot_pnp.env_config import make_env

    key = json.dumps(env_args, sort_keys=True)
    if key not in _ENVS:
        _ENVS[key] = make_env(render_mode=None, **env_args)
    return _ENVS[key]


def rollout_success(ckpt: Path, n_episodes: int, env_args: dict | None = None, seed: int = EVAL_SEED) -> dict:
    """Closed-loop success (%) of a checkpoint over seeds seed .. seed + n - 1 (in-process rollouts)."""
    from lerobot_pnp.closed_loop import run_episode
    from lerobot_pnp.evaluation.checkpoints import load_policy

    loaded = load_policy(ckpt)
    env = _env(env_args or {})
    start = time.perf_counter()
    ok = sum(run_episode(env, loaded, seed + i).success for i in range(n_episodes))
    return {"pc_success": 100.0 * ok / n_episodes, "n_episodes": n_episodes, "eval_s": time.perf_counter() - start}


def lerobot_eval_success(ckpt: Path, out: Path, n_episodes: int, env_args: dict | None = None) -> dict:
    from lerobot_pnp.demo import EvalSpec, run_eval

    if out.exists():
        shutil.rmtree(out)
    start = time.perf_counter()
    res = run_eval(ckpt, out, EvalSpec(out.name, n_episodes, dict(env_args or {})), EVAL_SEED, 50)
    res["eval_s"] = time.perf_counter() - start
    return res


def train(dataset: tuple[str, str], out: Path, progress: bool = False, **kwargs):
    from lerobot_pnp.policy import PnpLstmConfig
    from lerobot_pnp.train_fast import TrainFastConfig, train_fast

    policy_kwargs = kwargs.pop("policy", {})
    cfg = TrainFastConfig(
        dataset_repo_id=dataset[0],
        dataset_root=dataset[1],
        output_dir=str(out),
        overwrite=True,
        progress=progress,
        policy=PnpLstmConfig(**policy_kwargs),
        **kwargs,
    )
    if out.exists():
        shutil.rmtree(out)
    start_wall = time.time()
    start = time.perf_counter()
    result = train_fast(cfg)
    return result, start_wall, time.perf_counter() - start


def checkpoints(run_dir: Path) -> list[tuple[int, Path]]:
    found = []
    for d in (run_dir / "checkpoints").iterdir():
        if d.name.isdigit() and (d / "pretrained_model" / "model.safetensors").is_file():
            found.append((int(d.name), d / "pretrained_model"))
    return sorted(found)
