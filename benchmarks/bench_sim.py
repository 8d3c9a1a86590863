"""Simulation and expert throughput, measured side by side in one run.

Prints: raw ``mj_step`` rate of the scene (arm holding still, cube resting); expert episodes/s in keyframe
and dense mode; and the ratio of an expert episode's wall time to the cost of the physics steps it
contains, measured as the time spent inside ``mj_step`` during the episode (contacts with the gripper make
those steps dearer than idle ones, so the ratio to the idle rate is printed too). Target: IK + FSM +
interpolation + env overhead under 50 % of the physics cost.

    OMP_NUM_THREADS=1 python benchmarks/bench_sim.py [--n_episodes 100]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco

from lerobot_pnp import robot
from lerobot_pnp.sim.env_config import make_env
from lerobot_pnp.sim.expert import run_expert_episode


def raw_step_rate(n_steps: int = 20000) -> float:
    """mj_step calls per second on the scene with the arm holding a pose and the cube on the table."""
    model = mujoco.MjModel.from_xml_path(str(robot.scene_path()))
    data = mujoco.MjData(model)
    data.ctrl[:7] = robot.NEUTRAL_Q
    data.qpos[:7] = robot.NEUTRAL_Q
    mujoco.mj_forward(model, data)
    start = time.perf_counter()
    for _ in range(n_steps):
        mujoco.mj_step(model, data)
    return n_steps / (time.perf_counter() - start)


class _TimedStep:
    """Wraps mujoco.mj_step to add up the time spent inside it (the episode's own physics cost)."""

    def __init__(self):
        self.inner, self.seconds = mujoco.mj_step, 0.0

    def __call__(self, *args):
        start = time.perf_counter()
        self.inner(*args)
        self.seconds += time.perf_counter() - start


def expert_rate(control_mode: str, episodes: int, step_rate: float) -> dict:
    env = make_env(control_mode=control_mode, render_mode=None)
    physics = env.unwrapped.physics
    run_expert_episode(env, seed=10_000)  # warm-up
    timed = _TimedStep()
    mujoco.mj_step = timed
    wall, physics_steps = 0.0, 0
    try:
        for seed in range(episodes):
            start = time.perf_counter()
            run_expert_episode(env, seed=seed)
            wall += time.perf_counter() - start
            physics_steps += round(physics.data.time / physics.timestep)
    finally:
        mujoco.mj_step = timed.inner
    return {
        "episodes_per_s": episodes / wall,
        "physics_steps_per_episode": physics_steps / episodes,
        "wall_over_physics": wall / timed.seconds,
        "wall_over_raw_rate": wall / (physics_steps / step_rate),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n_episodes", type=int, default=100)
    args = parser.parse_args()
    rate = raw_step_rate()
    print(f"raw mj_step rate: {rate:,.0f} steps/s ({1e6 / rate:.1f} us/step)")
    for name, gym_id, n in (
        ("keyframe", "keyframe", args.n_episodes),
        ("dense", "dense", max(10, args.n_episodes // 4)),
    ):
        r = expert_rate(gym_id, n, rate)
        overhead = r["wall_over_physics"] - 1
        print(
            f"expert {name:8s}: {r['episodes_per_s']:6.1f} episodes/s, "
            f"{r['physics_steps_per_episode']:.0f} physics steps/episode; episode cost / its physics cost "
            f"(time inside mj_step) = {r['wall_over_physics']:.2f} -> IK + FSM + env overhead {overhead:.0%} "
            f"(target < 50%: {'PASS' if overhead < 0.5 else 'FAIL'}); "
            f"episode cost / (steps at the raw idle rate) = {r['wall_over_raw_rate']:.2f}"
        )


if __name__ == "__main__":
    main()
