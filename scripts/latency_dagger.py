"""One DAgger round under the trained latency, from the held-out study's recovering checkpoints.

The planner loses its re-grasps near the target at two steps of latency, though the same network re-picks there
at one step. One untried lever is to show it, under the latency it is
trained on, the states it visits itself, labelled by the expert. This runs one round of ``lerobot-pnp dagger``
on top of a study checkpoint (``outputs/heldout/train/recovering/seedN``, round 0 not trained again): 300
rollouts cycled over one suite (``train_latency``: the `full` task with 0 or 1 step of latency; ``nominal``:
the task as recorded, no latency), the expert's label executed with probability ``beta``, every visited state
labelled, aggregated with the study's demonstrations and trained on from the checkpoint for 100 epochs (the
study's DAgger warm start). Each round is evaluated on ``heldout_latency_2`` (200 episodes from the study's eval
seed 100,000, DAgger's serial evaluator, the same seeds for round 0 and round 1).

    python scripts/latency_dagger.py 1000 train_latency 0.5 lat1     # -> outputs/latency_dagger/lat1_s1000
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from lerobot_pnp.dagger import DaggerConfig, run_dagger
from lerobot_pnp.train_fast.config import policy_config_from_dict

STUDY = Path("outputs/heldout")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("seed", type=int, help="the study's training seed (1000, 1001, 1002)")
    p.add_argument("suite", help="the rollouts' suite (train_latency, nominal, ...)")
    p.add_argument("beta", type=float, help="probability of executing the expert's label (1: expert rollouts)")
    p.add_argument("name", help="run name: outputs/latency_dagger/<name>_s<seed>")
    a = p.parse_args()
    ckpt = STUDY / "train" / "recovering" / f"seed{a.seed}" / "checkpoints" / "last" / "pretrained_model"
    policy = policy_config_from_dict(json.loads((ckpt / "config.json").read_text()))
    summary = run_dagger(
        DaggerConfig(
            output_dir=f"outputs/latency_dagger/{a.name}_s{a.seed}",
            base_root=str(STUDY / "dataset"),
            base_repo_id="local/dataset",
            round0_checkpoint=str(ckpt),
            rounds=1,
            rollouts_per_round=300,
            beta=a.beta,
            rollout_suites=[a.suite],
            eval_suites=["heldout_latency_2"],
            n_episodes=200,
            eval_seed=100_000,
            policy=policy,
            epochs=300,
            warm_start_epochs=100,
            batch_size=32,
            seed=a.seed,
            test_fraction=0.2,
            progress=False,
        )
    )
    print(summary["table"])


if __name__ == "__main__":
    main()
