"""Where the recovering planner loses episodes at two steps of latency: its decisions, the gate's
waits and the failures, paired episode by episode with the trained latency of one step.

A protocol checkpoint (``outputs/RUN/train_done.json`` from ``scripts/heldout_protocol_eval.py``) runs the
episodes of ``heldout_latency_2`` (eval seeds from ``--seed``) at latency 1 and at latency 2, one env at a time
(``run_episode``). Per episode it counts the planner's decisions (steps on which the gate let it step its
network), the moves among them (commands the gate counts as moves), the gate's waits and its stale decisions (planned while the last two
steps both moved the arm or gripper, so that the observation misses two moves, where training showed one); and where an episode
fails, how far the object ended from the place target. A failure at two steps is then

* ``fails_at_latency_1``: the planner fails that episode at its trained latency too;
* ``same_decisions``: it makes no more than 2 decisions more than at latency 1, so the gate's waits alone took
  it past the budget;
* ``more_decisions``: its plan itself got longer (repeated attempts).

``--oracle_gate`` also runs two steps with the gate's decision replaced by the simulator's truth: the planner
steps unless both of the last two steps moved the arm (0.01 rad) or the gripper (0.05), so it never plans on
an observation two moves old (the gate counts arrivals from the observations, and some of its decisions are).

    OMP_NUM_THREADS=1 python scripts/latency_decisions.py s0 s1 s2 --oracle_gate --out docs/results/latency_decisions.json
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np
import protocol_runs  # scripts/: the protocol runs on disk
import torch

from lerobot_pnp.evaluation.checkpoints import load_policy
from lerobot_pnp.evaluation.closed_loop import run_episode
from lerobot_pnp.evaluation.stats import Rate
from lerobot_pnp.policy import observation_gate
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.sim.suites import SUITES

MOVED_Q, MOVED_GRIP = 0.01, 0.05  # rad, gripper opening: a step that moved the arm or the gripper (truth)


class Counting:
    """Wraps ``ObservationGate`` for one env: counts each episode's decisions, moves and waits, and optionally
    replaces its decision by the simulator's truth (``oracle``)."""

    def __init__(self, physics, latency: int, oracle: bool):
        self.physics, self.latency, self.oracle = physics, latency, oracle
        self.episode: dict = {}
        self.original = observation_gate.ObservationGate.decide, observation_gate.ObservationGate.update

    def __enter__(self):
        decide, update = self.original
        counter = self

        def counted_decide(gate, x):
            out = decide(gate, x)
            truth = np.append(counter.physics.arm_qpos(), counter.physics.gripper_opening())
            history = counter.episode.setdefault("truth", [])
            history.append(truth)
            lag = counter.latency
            moved = [
                np.abs(a[:7] - b[:7]).max() > MOVED_Q or abs(a[7] - b[7]) > MOVED_GRIP
                for a, b in zip(history[-lag:], history[-lag - 1 : -1], strict=False)
            ]
            two_unseen = sum(moved) > 1  # the observation (lag steps old) misses two moves
            if counter.oracle:
                out = torch.tensor([not two_unseen], device=x.device)
            counter.episode["stale"] = counter.episode.get("stale", 0) + int(bool(out[0]) and two_unseen)
            return out

        def counted_update(gate, decided, new_action, old_action):
            unseen = gate._unseen.clone()
            update(gate, decided, new_action, old_action)
            moves = gate._unseen - unseen  # the gate's own count of the moves decided now
            for key, value in (("decisions", decided), ("moves", moves), ("waits", ~decided)):
                counter.episode[key] = counter.episode.get(key, 0) + int(value.sum())

        observation_gate.ObservationGate.decide = counted_decide
        observation_gate.ObservationGate.update = counted_update
        return self

    def __exit__(self, *exc):
        observation_gate.ObservationGate.decide, observation_gate.ObservationGate.update = self.original


def run(checkpoint: Path, latency: int, seeds: list[int], oracle: bool) -> dict[int, dict]:
    cfg = SUITES["heldout_latency_2"].env_configs(BaxterPnPEnvConfig.from_source(str(protocol_runs.TASK_ROOT)))[0]
    cfg.obs_latency = latency
    loaded = load_policy(checkpoint, env_cfg=cfg)
    env = make_env(cfg, render_mode=None)
    base = env.unwrapped
    out = {}
    with Counting(base.physics, latency, oracle) as counter:
        for seed in seeds:
            counter.episode = {}
            ep = run_episode(env, loaded, seed)
            obj, _ = base.physics.object_pose()
            out[seed] = {
                "success": ep.success,
                "steps": ep.num_steps,
                "decisions": counter.episode.get("decisions", 0),
                "moves": counter.episode.get("moves", 0),
                "waits": counter.episode.get("waits", 0),
                "stale": counter.episode.get("stale", 0),
                "events": ep.info.get("perturbations") or "none",
                "object_to_target_cm": round(100 * float(np.linalg.norm(obj[:2] - base.pnp_task.place_xy)), 2),
            }
    env.close()
    return out


def summary(episodes: dict[int, dict]) -> dict:
    rate = Rate.of([e["success"] for e in episodes.values()])
    mean = {
        k: round(float(np.mean([e[k] for e in episodes.values()])), 2)
        for k in ("steps", "decisions", "moves", "waits", "stale")
    }
    return {"successes": rate.successes, "n": rate.n, "wilson95": list(rate.interval), "mean_per_episode": mean}


def distance_bin(cm: float) -> str:
    return "<2 cm" if cm < 2 else "2-3 cm" if cm < 3 else "3-8 cm" if cm < 8 else ">=8 cm"


def paired(one: dict[int, dict], two: dict[int, dict]) -> dict:
    """The failures at two steps, by what happened to the same episode at one step, and where the object ended."""
    kinds, ends = Counter(), Counter()
    for seed, e2 in two.items():
        if e2["success"]:
            continue
        e1 = one[seed]
        kind = (
            "fails_at_latency_1"
            if not e1["success"]
            else "same_decisions"
            if e2["decisions"] <= e1["decisions"] + 2
            else "more_decisions"
        )
        kinds[kind] += 1
        ends[f"{kind}: object {distance_bin(e2['object_to_target_cm'])} from the target"] += 1
    both = [s for s in two if two[s]["success"] and one[s]["success"]]
    return {
        "failures_at_2": dict(kinds),
        "failures_at_2_by_end": dict(sorted(ends.items())),
        "decisions_2_minus_1_where_both_succeed": round(
            float(np.mean([two[s]["decisions"] - one[s]["decisions"] for s in both])), 3
        ),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+", help="protocol runs: outputs/RUN/train_done.json names the checkpoint")
    p.add_argument("--n_episodes", type=int, default=200)
    p.add_argument("--seed", type=int, default=10_000_000, help="first eval seed (the protocol script's)")
    p.add_argument("--oracle_gate", action="store_true", help="also two steps with the simulator's truth as gate")
    p.add_argument("--out", type=Path)
    args = p.parse_args()
    seeds = list(range(args.seed, args.seed + args.n_episodes))
    result: dict = {"suite": "heldout_latency_2", "first_seed": args.seed, "episodes": args.n_episodes, "runs": {}}
    for name in args.runs:
        checkpoint = protocol_runs.checkpoint(name)
        one, two = run(checkpoint, 1, seeds, False), run(checkpoint, 2, seeds, False)
        entry = {"latency_1": summary(one), "latency_2": summary(two), "paired": paired(one, two)}
        if args.oracle_gate:
            entry["latency_2_oracle_gate"] = summary(run(checkpoint, 2, seeds, True))
        result["runs"][name] = entry
        print(name, json.dumps(entry), flush=True)
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
