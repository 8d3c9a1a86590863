"""How large DART's joint noise is on the task's scale: what a noise setting does to the expert's hand and to
its demonstrations (the measurement that picks ``dart.sigma``).

``python benchmarks/dart_noise.py [--config configs/dart_paper.json] [--n_episodes 40] SIGMA[,FLIP] ...`` prints,
per setting, in the task of a dagger config (its preset with ``env_changes``, the rollout suite ``nominal``):
the end-effector displacement that the joint noise causes at the expert's keyframes (forward kinematics of
the clean keyframe and of the noised one, median and 90th percentile over keyframes and draws), and what the
noisy expert does in the task as DAgger's DART round runs it (``labelled_rollout`` with ``beta = 1``, seeds
``1,000,000 + i`` as round 1's): success, episodes with a recovery (a label phase returning to an earlier one),
labelled frames per episode.

``python benchmarks/dart_noise.py --rollouts ROLLOUTS_DIR ...`` instead reads DAgger rollout datasets
(``round_XX/rollouts``) and prints, per dataset, the recoveries it teaches (each episode's first return of
the label phase to an earlier one) by the phase left: after the close (a missed grasp), in transport (pick
retract .. place approach: a drop), after the place (the object off the target); and how far from the hand
(xy, cm) the object was at their first frame.
"""

from __future__ import annotations

import argparse

import draccus
import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.dagger import DaggerConfig
from lerobot_pnp.dagger.dart import DartNoise
from lerobot_pnp.dagger.loop import base_env_config
from lerobot_pnp.dagger.rollouts import labelled_rollout, suite_env
from lerobot_pnp.sim.expert import run_expert_episode


class _Idle:
    """The 'policy' beside the acting expert (beta 1: never executed)."""

    def __init__(self, env):
        self.env = env

    def reset(self):
        pass

    def act(self, obs):
        return np.append(self.env.unwrapped.physics.arm_command(), robot.GRIPPER_OPEN).astype(np.float32)


def hand_displacement(env, sigma: float, seeds: range, draws: int = 20) -> tuple[float, float]:
    """Median and 90th percentile (m) of the gripper-site displacement caused by joint noise ``sigma``."""
    ik = env.unwrapped.physics.ik
    rng = np.random.default_rng(0)
    shifts = []
    for seed in seeds:
        for q in run_expert_episode(env, seed).keyframes[1:, : robot.N_JOINTS]:
            clean, _ = ik.forward(q)
            for _ in range(draws):
                noisy = np.clip(q + rng.normal(0, sigma, robot.N_JOINTS), robot.JOINT_LOWER, robot.JOINT_UPPER)
                shifts.append(np.linalg.norm(ik.forward(noisy)[0] - clean))
    return float(np.median(shifts)), float(np.percentile(shifts, 90))


def noisy_expert(env, dart: DartNoise, episodes: int) -> dict:
    succ = recovered = frames = 0
    for i in range(episodes):
        ep = labelled_rollout(env, _Idle(env), 1_000_000 + i, "nominal", 1.0, dart)
        succ += ep.success
        frames += len(ep.phases)
        recovered += bool(np.any(np.diff(ep.phases) < 0))
    return {"success": succ, "recovered": recovered, "frames_per_episode": frames / episodes}


RECOVERY_KINDS = {"missed grasp": (3, 3), "drop": (4, 6), "off target": (7, 9)}  # the phase left (inclusive)


def restart_offsets(root: str, env) -> tuple[np.ndarray, np.ndarray]:
    """Per episode's first recovery in ``root``: the hand-to-object xy distance (m) at its first frame, and
    the label phase it left."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ik = env.unwrapped.physics.ik
    frames = LeRobotDataset("local/rollouts", root=root).hf_dataset.with_format("numpy")[:]
    episode, phase = frames["episode_index"].reshape(-1), frames["phase.index"].reshape(-1)
    offsets, left = [], []
    for e in np.unique(episode):
        idx = np.flatnonzero(episode == e)
        back = np.flatnonzero(np.diff(phase[idx]) < 0)
        if len(back):
            k = idx[back[0] + 1]
            hand, _ = ik.forward(frames["observation.state"][k][: robot.N_JOINTS])
            offsets.append(np.linalg.norm(hand[:2] - frames["observation.environment_state"][k][:2]))
            left.append(phase[k - 1])
    return np.asarray(offsets), np.asarray(left)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("settings", nargs="*", help="SIGMA[,GRIPPER_FLIP]")
    ap.add_argument("--rollouts", nargs="*", default=[], help="rollout dataset folders (round_XX/rollouts)")
    ap.add_argument("--config", default="configs/dart_paper.json", help="a dagger config: its task (env_changes)")
    ap.add_argument("--n_episodes", type=int, default=40)
    args = ap.parse_args()
    env = suite_env(base_env_config(draccus.parse(DaggerConfig, config_path=args.config, args=[])), "nominal")
    for root in args.rollouts:
        offsets, left = restart_offsets(root, env)
        d = 100 * offsets
        kinds = ", ".join(f"{k} {int(((left >= lo) & (left <= hi)).sum())}" for k, (lo, hi) in RECOVERY_KINDS.items())
        print(f"{root}: {len(d)} recoveries ({kinds}); object-hand xy at the restart: median {np.median(d):.1f} "
              f"cm, 90th percentile {np.percentile(d, 90):.1f} cm, max {d.max():.1f} cm")  # fmt: skip
    if args.settings:
        print("| sigma (rad) | gripper flip | hand shift median / p90 (cm) | noisy expert success | with a recovery | "
              "frames / episode |\n|---|---|---|---|---|---|")  # fmt: skip
        for spec in args.settings:
            sigma, flip = (float(x) for x in (spec.split(",") + ["0"])[:2])
            med, p90 = hand_displacement(env, sigma, range(5)) if sigma > 0 else (0.0, 0.0)
            r = noisy_expert(env, DartNoise(sigma, flip), args.n_episodes)
            n = args.n_episodes
            print(f"| {sigma:g} | {flip:g} | {100 * med:.1f} / {100 * p90:.1f} | {r['success']}/{n} | "
                  f"{r['recovered']}/{n} | {r['frames_per_episode']:.1f} |", flush=True)  # fmt: skip
    env.close()


if __name__ == "__main__":
    main()
