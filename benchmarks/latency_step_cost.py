"""What the 40-keyframe budget leaves to a controller that waits to see each of its moves (latency).

The gate lets a planner trained on observations at most ``k`` steps old (``observation_gate``, ``in_flight = k``)
plan while at most ``k`` of its moves are unobserved. At ``heldout_latency_2`` the recovering recipe (``k = 1``)
therefore never commands three moves in three consecutive steps: it waits one step after every second move
(a hold keyframe, which moves nothing, does not count). This measures what a waiting rule alone costs in the
40-keyframe budget, without any learning: the privileged scripted expert (it plans from the simulator's state,
so the latency itself cannot hurt it, and it sees every disturbance at once) holds keyframes for ``hold``
extra steps, on a suite's episodes and the study's eval seeds. ``hold = 0`` is the expert as the benchmark
measures it; ``--holds`` holds every moving keyframe.

``--variants`` measures where the waits cost the budget (``hold = 1``, both seed blocks): ``every_move`` (a wait
after every move, twice the gate's), ``gripper`` (wait only for a gripper command and for the descent before
one: the waits that the gate's run-ahead experiments found cannot be skipped), ``after_gripper`` (only for
gripper commands), ``every_move_no_hold`` (every move waited for, but the keyframe that reaches place/start,
which repeats the pick retract's command, is not executed: one fewer keyframe per pick) and ``gate`` (the
gate's own schedule at two steps: a move waits while the last ``1 + hold`` steps both moved).

With ``--planner EVALS_DIR`` (a study's ``evals/recovering``) it pairs the expert's episodes with the planner's
records of the same suite and seeds (each training seed): the planner's failures that the waiting expert also
fails, and the other way round.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/latency_step_cost.py --holds 0 1 2 \
        --planner outputs/heldout/evals/recovering --out docs/results/latency_step_cost.json
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/latency_step_cost.py --variants --out docs/results/latency_wait_variants.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from lerobot_pnp.evaluation.records import EpisodeRecord, summarize
from lerobot_pnp.evaluation.stats import Rate, paired_comparison
from lerobot_pnp.robot import Phase
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.sim.expert import FSMExpert
from lerobot_pnp.sim.suites import get_suites

MOVE_TOL = 1e-3  # a keyframe that changes the command by less (a hold keyframe) is not waited for


WAITS = ("every_move", "gripper", "after_gripper", "every_move_no_hold", "gate")
_BEFORE_GRIPPER = (Phase.PICK_APPROACH, Phase.PLACE_APPROACH)  # leaving these: the descents before a close / open


def waiting_expert(env, seed: int, hold: int, wait: str = "every_move") -> EpisodeRecord:
    """One episode of the expert holding some keyframes ``hold`` extra steps (``wait``: which, see the module's
    docstring); the env's budget applies."""
    env.reset(seed=seed)
    expert = FSMExpert(env)
    previous, steps = expert.command, 0
    recent: list[bool] = []  # did each executed step move ("gate")

    def step(command: np.ndarray) -> EpisodeRecord | None:
        """Execute one step; the episode's record when it ended the episode."""
        nonlocal steps
        _, _, terminated, truncated, info = env.step(command)
        steps += 1
        return EpisodeRecord.from_info(seed, info, steps, (np.nan, np.nan)) if terminated or truncated else None

    while True:
        command = expert.next_keyframe()
        moved = np.linalg.norm(command - previous) > MOVE_TOL
        gripper = command[7] != previous[7]
        # the gate's schedule at latency 1 + hold, for a planner trained on 1: at most one move unseen, so a move
        # waits (the last command held) before it is executed, where the other rules wait after it
        if wait == "gate":
            while moved and sum(recent[-(1 + hold) :]) > 1:
                if record := step(previous):
                    return record
                recent.append(False)
            recent.append(bool(moved))
        if wait == "every_move_no_hold" and expert.last_phase == Phase.PICK_RETRACT and not moved:
            previous = command
            continue
        waits_after = {
            "every_move": moved,
            "every_move_no_hold": moved,
            "gripper": gripper or (moved and expert.last_phase in _BEFORE_GRIPPER),
            "after_gripper": gripper,
            "gate": False,
        }[wait]
        previous = command
        for _ in range(1 + (hold if waits_after else 0)):
            if record := step(command):
                return record


def run(suite: str, holds: list[int], seeds: list[int], wait: str = "every_move") -> dict[int, list[EpisodeRecord]]:
    base = BaxterPnPEnvConfig.from_dict({"preset": "full"})
    (cfg,) = get_suites([suite])[0].env_configs(base)
    env = make_env(cfg, render_mode=None)
    out = {h: [waiting_expert(env, s, h, wait) for s in seeds] for h in holds}
    env.close()
    return out


def variants(suite: str, seed_blocks: list[int], episodes: int) -> dict:
    """``hold = 1`` under each ``WAITS`` rule, pooled over the seed blocks."""
    out = {}
    for wait in WAITS:
        eps = [e for b in seed_blocks for e in run(suite, [1], list(range(b, b + episodes)), wait)[1]]
        out[wait] = summary(eps)
        rate = Rate(out[wait]["successes"], out[wait]["n"])
        print(f"{wait}: {rate.successes}/{rate.n} = {rate}, "
              f"{out[wait]['mean_steps_success']:.1f} keyframes per success", flush=True)  # fmt: skip
    return out


def summary(episodes: list[EpisodeRecord]) -> dict:
    rate, counts = Rate.of([e.success for e in episodes]), summarize(episodes)
    steps = [e.steps for e in episodes if e.success]
    return {"successes": rate.successes, "n": rate.n, "rate": rate.rate, "wilson95": list(rate.interval),
            "mean_steps_success": float(np.mean(steps)) if steps else None, "failures": counts["by_cause"]}  # fmt: skip


def paired(expert: list[EpisodeRecord], planner_dir: Path, suite: str) -> dict:
    """Per training seed: the planner's and the waiting expert's outcomes on the seeds both ran."""
    by_seed = {e.seed: e.success for e in expert}
    out = {}
    for record in sorted(planner_dir.glob(f"*/{suite}.json")):
        planner = {e["seed"]: e["success"] for e in json.loads(record.read_text())["episodes"]}
        both = paired_comparison(planner, by_seed)  # a: the planner, b: the waiting expert
        planner_successes = sum(planner[s] for s in planner if s in by_seed)
        out[record.parent.name] = {
            "n": both.n,
            "planner_successes": planner_successes,
            "expert_successes": planner_successes - both.a_only + both.b_only,
            "both_fail": both.n - planner_successes - both.b_only,
            "planner_only_fails": both.b_only,
            "expert_only_fails": both.a_only,
        }
    return out


def holds(args) -> dict:
    """Each ``--holds`` value on each seed block, pooled, optionally paired with the planner."""
    result: dict = {"suite": args.suite, "what": __doc__.split("\n\n")[1].replace("\n", " "), "holds": {}}
    for hold in args.holds:
        result["holds"][hold] = {}
    for block in args.seed_blocks:
        episodes = run(args.suite, args.holds, list(range(block, block + args.n_episodes)))
        for hold, eps in episodes.items():
            result["holds"][hold][str(block)] = summary(eps)
            if args.planner and block == args.seed_blocks[0]:
                result["holds"][hold]["paired_with_planner"] = paired(eps, args.planner, args.suite)
    for hold, blocks in result["holds"].items():
        pooled = [b for k, b in blocks.items() if k.isdigit()]
        rate = Rate(sum(b["successes"] for b in pooled), sum(b["n"] for b in pooled))
        blocks["pooled"] = {
            "successes": rate.successes,
            "n": rate.n,
            "rate": rate.rate,
            "wilson95": list(rate.interval),
        }
        print(f"hold {hold}: {rate.successes}/{rate.n} = {rate}", flush=True)
    return result


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--suite", default="heldout_latency_2")
    p.add_argument("--holds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--n_episodes", type=int, default=200, help="per eval-seed block")
    p.add_argument("--seed_blocks", type=int, nargs="+", default=[100_000, 10_000_000],
                   help="first eval seeds: the study's and the held-out protocol script's")  # fmt: skip
    p.add_argument("--planner", type=Path, help="a study's evals/recovering folder to pair with (seed block 1)")
    p.add_argument("--variants", action="store_true", help="which waits cost the budget (hold 1, every WAITS rule)")
    p.add_argument("--out", type=Path)
    args = p.parse_args()
    if args.variants:
        result = {"suite": args.suite, "what": __doc__.split("\n\n")[2].replace("\n", " "), "seed_blocks": args.seed_blocks,
                  "episodes_per_block": args.n_episodes, "hold": 1, "waits": variants(args.suite, args.seed_blocks, args.n_episodes)}  # fmt: skip
    else:
        result = holds(args)
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
