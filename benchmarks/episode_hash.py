"""One hash of many episodes: the scripted expert's and a blind policy's (the action space's seeded samples), on the
`full` task and its disturbance-heavy suites. Run it before and after a change to the simulator, the task or its
disturbances: the same hash means every episode, observation and info field stayed the same, bit for bit.

    OMP_NUM_THREADS=1 MUJOCO_GL=egl python benchmarks/episode_hash.py [--n_episodes 10]
"""

from __future__ import annotations

import argparse
import hashlib
import time

import numpy as np

from lerobot_pnp.errors import PnPError
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.sim.expert import run_expert_episode
from lerobot_pnp.sim.stock_suites import suite_configs

SUITES = (
    "train_displace,train_drop,train_grasp_miss,heldout_far_displace,heldout_double_drop,"
    "heldout_late_grasp_miss,heldout_far_drop"
)
BLIND_STEPS = 25


def episode_hash(episodes: int) -> str:
    """The hash of ``episodes`` expert episodes and as many blind rollouts per suite (and of the plain task)."""
    digest = hashlib.sha256()
    configs = {
        "full": BaxterPnPEnvConfig(preset="full"),
        **suite_configs(BaxterPnPEnvConfig(preset="full", task=SUITES)),
    }
    for cfg in configs.values():
        env = make_env(cfg, render_mode=None)
        for seed in range(episodes):
            try:
                ep = run_expert_episode(env, seed)
                for arr in (ep.states, ep.actions):
                    digest.update(np.ascontiguousarray(np.asarray(arr)).tobytes())
            except PnPError as err:  # a failure is an outcome too
                digest.update(repr(err).encode())
            env.reset(seed=1000 + seed)
            env.action_space.seed(seed)
            for _ in range(BLIND_STEPS):
                obs, _, terminated, truncated, info = env.step(env.action_space.sample())
                digest.update(np.ascontiguousarray(obs["agent_pos"]).tobytes())
                digest.update(str(sorted((k, str(v)) for k, v in info.items())).encode())
                if terminated or truncated:
                    break
        env.close()
    return digest.hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n_episodes", type=int, default=10, help="expert episodes and blind rollouts per suite")
    args = parser.parse_args()
    start = time.process_time()
    print(episode_hash(args.n_episodes), f"({time.process_time() - start:.0f} s CPU)")


if __name__ == "__main__":
    main()
