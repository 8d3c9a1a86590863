"""What the visual variation costs a camera episode: every visual suite beside the scene as modelled, in one run.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_visual.py [--sizes 64x64 320x240] [--rounds 12]
        [--out docs/results/bench_visual.json]

A camera episode is the scripted expert's keyframe episode on the `full` task with the front and wrist cameras
rendered at every step (the env's observation, the camera planner's setting: no render effects), from its reset to
its end. Per image size, each variant (``nominal``, ``train_visual`` and every held-out visual suite, each the
suite's changes on that task) runs the same seeds, interleaved in rounds: one episode of every variant per round,
seed = round, each round starting at another variant, so that a shared machine's load falls on all alike. The
envs are built before the first round (the distractor slots are added once, when an env is built). Reported per
variant: the median CPU time per episode and per step, and the median over seeds of its cost over ``nominal``'s
on the same seed (the target: at most 1.20), and the variation's own CPU time per episode (``variation_ms``: the
draw and the model's fields written at reset, the image noise and blur of every frame) over ``nominal``'s episode
(``variation_share``; the target: at most 0.20). The expert does not see the pixels, so every variant simulates
exactly the same episodes: the ratio and the share measure the same cost, the share without the shared machine's
noise on two whole episodes.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

TARGET = 1.20  # the most a visual variation may multiply a camera episode's cost by


def variants() -> list[str]:
    from lerobot_pnp.sim.visual_suites import VISUAL_SUITES

    return ["nominal", *VISUAL_SUITES]


class VisualClock:
    """CPU time spent in an env's visual variation (``SceneVariation.reset`` and ``.images``), wrapped in place."""

    def __init__(self, env):
        self.seconds = 0.0
        scene = env.unwrapped.pnp_task.scene
        if scene is not None:
            scene.reset, scene.images = self._timed(scene.reset), self._timed(scene.images)

    def _timed(self, method):
        def timed(*args, **kwargs):
            t0 = time.process_time()
            try:
                return method(*args, **kwargs)
            finally:
                self.seconds += time.process_time() - t0

        return timed


def episode_cost(size: tuple[int, int], rounds: int) -> dict:
    """Per variant: median CPU ms per episode and per step over ``rounds`` seeds; the median over seeds of its
    cost over ``nominal``'s on the same seed (the two episodes run one after the other, so a change in the
    machine's load falls on both); and the CPU time of the variation itself per episode (drawing and writing it at
    reset, degrading the frames) over ``nominal``'s episode, which a shared machine's load disturbs far less."""
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
    from lerobot_pnp.sim.expert import run_expert_episode
    from lerobot_pnp.sim.suites import SUITES

    width, height = size
    base = BaxterPnPEnvConfig(preset="full", cameras=["front", "wrist"], image_height=height, image_width=width)
    envs = {name: make_env(SUITES[name].env_configs(base)[0]) for name in variants()}
    cpu: dict[str, list[float]] = {name: [] for name in envs}
    own: dict[str, list[float]] = {name: [] for name in envs}
    steps: dict[str, list[int]] = {name: [] for name in envs}
    for env in envs.values():  # warm: the renderers are made on first use
        run_expert_episode(env, 10_000)
    clocks = {name: VisualClock(env) for name, env in envs.items()}
    names = list(envs)
    for seed in range(rounds):
        for k in range(len(names)):  # each round in another order: no variant always runs first
            name = names[(k + seed) % len(names)]
            before, t0 = clocks[name].seconds, time.process_time()
            episode = run_expert_episode(envs[name], seed)
            cpu[name].append(time.process_time() - t0)
            own[name].append(clocks[name].seconds - before)
            steps[name].append(episode.num_frames)
    for env in envs.values():
        env.close()
    nominal = statistics.median(cpu["nominal"])
    out = {}
    for name in envs:
        ratios = [v / n for v, n in zip(cpu[name], cpu["nominal"], strict=True)]
        out[name] = {
            "episode_ms": round(1e3 * statistics.median(cpu[name]), 1),
            "step_ms": round(1e3 * sum(cpu[name]) / sum(steps[name]), 2),
            "vs_nominal": round(statistics.median(ratios), 3),
            "variation_ms": round(1e3 * statistics.median(own[name]), 2),
            "variation_share": round(statistics.median(own[name]) / nominal, 3),
        }
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=["64x64", "320x240"], help="WIDTHxHEIGHT of the images")
    parser.add_argument("--rounds", type=int, default=12, help="episodes per variant (seeds 0 .. rounds-1)")
    parser.add_argument("--out", type=Path, help="write the result here as JSON")
    args = parser.parse_args()
    from lerobot_pnp.report.provenance import machine

    host = machine()
    command = f"benchmarks/bench_visual.py --sizes {' '.join(args.sizes)} --rounds {args.rounds}"
    result = {
        "command": command,
        "machine": {k: host.get(k) for k in ("cpu", "cores_available", "commit", "mujoco", "numpy", "date")},
        "load_before": round(os.getloadavg()[0], 2),
        "target_vs_nominal": TARGET,
        "cameras": ["front", "wrist"],
        "sizes": {},
    }
    for size in args.sizes:
        w, h = (int(v) for v in size.lower().split("x"))
        result["sizes"][size] = cost = episode_cost((w, h), args.rounds)
        worst = max((v["vs_nominal"], k) for k, v in cost.items())
        own = max((v["variation_share"], k) for k, v in cost.items())
        print(f"{size}: nominal {cost['nominal']['episode_ms']} ms/episode; most: {worst[1]} x{worst[0]}; "
              f"the variation's own cost at most {100 * own[0]:.1f} % ({own[1]})", flush=True)  # fmt: skip
    text = json.dumps(result, indent=1)
    if args.out:
        tmp = args.out.with_name(args.out.name + ".tmp")
        tmp.write_text(text + "\n")
        tmp.replace(args.out)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
