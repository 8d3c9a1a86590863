"""The recovering planner and DAgger, measured side by side on the same evaluation seeds.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_planner.py [--config configs/dagger.json]
        [--sections dagger,clocked,memoryless,latency] [--output_dir outputs/bench_planner]

dagger      ``lerobot-pnp dagger`` with the config (expert demos of the ``full`` task, round 0, N DAgger
            rounds), timed: demos, each round's rollouts + aggregation, each round's training. Prints the
            success table (Wilson 95 % intervals) per round and suite.
clocked     The paper's clocked two-LSTM on the same task: trained (fast path, same epochs) on the
            demonstrations that needed no recovery (exactly 10 frames: it cannot represent longer episodes),
            evaluated on the same suites and seeds.
memoryless  ``recurrent=False`` (the MLP trunk of matched parameter count), trained on the round-0
            demonstrations with the same recipe, and again on current observations only (no late
            episodes), same evaluation.
phase_told  The same matched MLP told the phase: the same demonstrations (same seeds) recorded with
            ``observe_phase`` (a one-hot of the phase the env infers from the true simulator state, appended
            to ``environment_state``; privileged), round 0 only (no DAgger), both of the memoryless
            control's recipes, same evaluation.
latency     ``select_action`` at batch 1, median over 2000 calls, recovering vs clocked (one torch thread).
lerobot_eval  (not in the default sections) the real ``lerobot-eval`` CLI on the recovering checkpoint of
            round ``--eval_round`` (default: the last), every eval suite, the same seeds and episode counts;
            prints its success beside the in-process one and the episodes on which they disagree.

Evaluation is in-process (``lerobot_pnp.dagger.evaluate``: env from ``make_env``, LeRobot's
``preprocess_observation`` -> pre-processor -> ``select_action`` -> post-processor -> ``env.step``).
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MUJOCO_GL", "egl")

import draccus
import numpy as np
import torch

torch.set_num_threads(1)

from lerobot_pnp.dagger import DaggerConfig, evaluate_checkpoint, run_dagger, write_table  # noqa: E402
from lerobot_pnp.dagger.loop import base_env_config  # noqa: E402
from lerobot_pnp.dagger.writer import LabelledEpisode, write_episodes  # noqa: E402
from lerobot_pnp.dataset.splits import range_spec, recorded_split, test_split  # noqa: E402


def log(msg: str) -> None:
    print(f"[bench_planner {time.strftime('%H:%M:%S')}] {msg}", flush=True)


def load_config(path: str, output_dir: str) -> DaggerConfig:
    with draccus.config_type("json"):
        cfg = draccus.parse(DaggerConfig, path, args=[f"--output_dir={output_dir}", "--progress=false"])
    return cfg


def ten_frame_demos(cfg: DaggerConfig, out: Path) -> tuple[Path, str, str]:
    """The demonstrations without a recovery (exactly 10 frames), rewritten as their own dataset."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = out / "clocked_demos"
    demos = Path(cfg.output_dir) / "demos"
    ds = LeRobotDataset(f"{cfg.base_repo_id}_demos", root=demos)
    t = ds.hf_dataset.with_format("numpy")[:]
    eps = t["episode_index"].reshape(-1)
    episodes = []
    for e in np.unique(eps):
        rows = np.flatnonzero(eps == e)
        rows = rows[np.argsort(t["frame_index"].reshape(-1)[rows])]
        if len(rows) != 10:
            continue
        episodes.append(
            LabelledEpisode(
                int(t["episode.seed"].reshape(-1)[rows[0]]),
                t["observation.state"][rows],
                t["observation.environment_state"][rows],
                t["action"][rows],
                t["phase.index"].reshape(-1)[rows],
            )
        )
    n = len(episodes)
    test = test_split(n, cfg.test_fraction)  # held out as DAgger's demos are
    if not root.is_dir():
        write_episodes(root, "local/clocked_demos", base_env_config(cfg), episodes, {"test": test})
    return root, "local/clocked_demos", test


def train(root: Path, repo: str, test: str, policy, cfg: DaggerConfig, out_dir: Path) -> tuple[Path, float]:
    from lerobot_pnp.train_fast import TrainFastConfig, train_fast

    done = out_dir / "done.json"
    if done.is_file():
        d = json.loads(done.read_text())
        return Path(d["checkpoint"]), d["train_s"]
    t0 = time.perf_counter()
    result = train_fast(
        TrainFastConfig(
            dataset_repo_id=repo, dataset_root=str(root), policy=policy, epochs=cfg.epochs,
            batch_size=cfg.batch_size, seed=cfg.seed, output_dir=str(out_dir), overwrite=True,
            test_episodes=test, progress=False,
        )
    )  # fmt: skip
    train_s = time.perf_counter() - t0
    done.write_text(json.dumps({"checkpoint": str(result.checkpoint_dir), "train_s": train_s}))
    return result.checkpoint_dir, train_s


def latency(ckpt: Path, calls: int = 2000) -> float:
    from lerobot_pnp.evaluation.checkpoints import load_policy

    p = load_policy(ckpt).policy
    feats = p.config.input_features
    batch = {k: torch.zeros(1, ft.shape[0]) for k, ft in feats.items()}
    times = []
    with torch.inference_mode():
        p.reset()
        for i in range(calls):
            if i % 10 == 0:
                p.reset()
            t0 = time.perf_counter()
            p.select_action(batch)
            times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e3


def cli_check(cfg: DaggerConfig, out: Path, rnd: int) -> dict:
    """Stock ``lerobot-eval`` (subprocess) on round ``rnd``'s checkpoint, suite by suite, against the
    in-process evaluation of the same seeds (``round_XX/eval.json``)."""
    from lerobot_pnp.report.cli_eval import EvalSpec, run_eval
    from lerobot_pnp.sim.suites import SUITES

    rdir = out / "dagger" / f"round_{rnd:02d}"
    ckpt = rdir / "train" / "checkpoints" / "last" / "pretrained_model"
    in_process = json.loads((rdir / "eval.json").read_text())
    report = {}
    for suite in cfg.eval_suites:
        spec = EvalSpec(suite, cfg.n_episodes, dict(SUITES[suite].parts[0]))  # DAgger suites have one part
        res = run_eval(ckpt, out / "lerobot_eval" / f"round_{rnd:02d}" / suite, spec, cfg.eval_seed, 50)
        ok = sum(res["per_episode"].values())
        report[suite] = {"successes": ok, "n": len(res["per_episode"]), "in_process": in_process[suite]["successes"]}
        log(f"lerobot-eval round {rnd} {suite}: {ok}/{len(res['per_episode'])} (in process "
            f"{in_process[suite]['successes']}/{in_process[suite]['n']})")  # fmt: skip
    (out / f"lerobot_eval_round{rnd:02d}.json").write_text(json.dumps(report, indent=2))
    return report


def _section_dagger(cfg: DaggerConfig, out: Path, env_cfg, results: dict, rows: list) -> None:
    t0 = time.perf_counter()
    summary = run_dagger(cfg)
    results["dagger"] = summary
    timings = summary["timings_s"]
    train_total = sum(v for k, v in timings.items() if k != "demos_s")
    log(f"dagger timings (s): {timings}")
    log(f"recovering policy, training incl. {cfg.rounds} DAgger rounds (rollouts, labels, aggregation, "
        f"retraining; demos and evaluation excluded): {train_total / 60:.1f} min; whole run incl. evaluation "
        f"{(time.perf_counter() - t0) / 60:.1f} min")  # fmt: skip
    for rnd in range(cfg.rounds + 1):
        f = out / "dagger" / f"round_{rnd:02d}" / "eval.json"
        if f.is_file():
            rows.append((f"recovering, round {rnd}" + (" (no DAgger)" if rnd == 0 else ""), json.loads(f.read_text())))


def _section_clocked(cfg: DaggerConfig, out: Path, env_cfg, results: dict, rows: list) -> None:
    root, repo, test = ten_frame_demos(cfg, out)
    policy = copy.deepcopy(cfg.policy)
    policy.mode, policy.subtask_loss_weight, policy.phase_loss_weight = "clocked", 0.0, 0.0
    ckpt, train_s = train(root, repo, test, policy, cfg, out / "clocked")
    log(f"clocked: trained in {train_s:.0f} s")
    res = evaluate_checkpoint(cfg, ckpt, env_cfg, out / "clocked" / "eval.json")
    rows.insert(0, ("clocked (paper), 10-frame demos", res))
    results["clocked_checkpoint"] = str(ckpt)


# The memoryless controls with both recipes: with the late episodes (the planner's recipe) and on current
# observations only (a model without memory cannot tell a late observation from a current one; measured,
# the late episodes help the plain MLP and hurt the phase-told one, so both are reported).
def _recipes(cfg: DaggerConfig) -> tuple[tuple[str, float], ...]:
    return (("late", cfg.policy.latency_augment_prob), ("current", 0.0))


def _section_memoryless(cfg: DaggerConfig, out: Path, env_cfg, results: dict, rows: list) -> None:
    """Round-0 data, like the phase-told control and the round-0 planner."""
    data, repo = out / "dagger" / "demos", f"{cfg.base_repo_id}_demos"
    test = range_spec(recorded_split(data, "test"))  # the split DAgger's demos were generated with
    for name, prob in _recipes(cfg):
        policy = copy.deepcopy(cfg.policy)
        policy.recurrent, policy.latency_augment_prob = False, prob
        rdir = out / ("memoryless_late" if name == "late" else "memoryless")
        ckpt, train_s = train(data, repo, test, policy, cfg, rdir)
        res = evaluate_checkpoint(cfg, ckpt, env_cfg, rdir / "eval.json")
        rows.append((f"memoryless (matched MLP), round-0 data, {name} observations in training", res))


def _section_phase_told(cfg: DaggerConfig, out: Path, env_cfg, results: dict, rows: list) -> None:
    for name, prob in reversed(_recipes(cfg)):  # "current" first: it writes the phase-told demonstrations
        told = copy.deepcopy(cfg)
        told.output_dir, told.rounds = str(out / ("phase_told_late" if name == "late" else "phase_told")), 0
        told.env_changes = {**cfg.env_changes, "observe_phase": True}
        told.policy.recurrent, told.policy.latency_augment_prob = False, prob
        if name == "late":  # the same phase-told demonstrations, written by the "current" run
            told.base_root, told.base_repo_id = str(out / "phase_told" / "demos"), f"{cfg.base_repo_id}_demos"
        summary = run_dagger(told)
        log(f"phase-told MLP ({name}) timings (s): {summary['timings_s']}")
        res = json.loads((Path(told.output_dir) / "round_00" / "eval.json").read_text())
        rows.append((f"memoryless (matched MLP) told the phase, round-0 data, {name} observations in training", res))


def _section_latency(cfg: DaggerConfig, out: Path, env_cfg, results: dict, rows: list) -> None:
    lat = {}
    for name, ckpt in (
        ("recovering", results.get("dagger", {}).get("final_checkpoint")),
        ("clocked", results.get("clocked_checkpoint")),
    ):
        if ckpt:
            lat[name] = latency(Path(ckpt))
            log(f"select_action batch 1, {name}: median {lat[name]:.3f} ms")
    results["select_action_ms"] = lat


# --sections, run in this order
SECTIONS = {
    "dagger": _section_dagger,
    "clocked": _section_clocked,
    "memoryless": _section_memoryless,
    "phase_told": _section_phase_told,
    "latency": _section_latency,
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="configs/dagger.json")
    ap.add_argument("--output_dir", default="outputs/bench_planner")
    ap.add_argument("--sections", default="dagger,clocked,memoryless,phase_told,latency")
    ap.add_argument("--rounds", type=int, default=None, help="override the config's DAgger rounds")
    ap.add_argument("--eval_round", type=int, default=None, help="lerobot_eval section: the round (default: last)")
    args = ap.parse_args()
    sections = set(args.sections.split(","))
    out = Path(args.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    cfg = load_config(args.config, str(out / "dagger"))
    if args.rounds is not None:
        cfg.rounds = args.rounds
    env_cfg = base_env_config(cfg)
    results: dict = {}
    rows: list[tuple[str, dict]] = []
    for name, section in SECTIONS.items():
        if name in sections:
            section(cfg, out, env_cfg, results, rows)
    if "lerobot_eval" in sections:
        results["lerobot_eval"] = cli_check(cfg, out, cfg.rounds if args.eval_round is None else args.eval_round)

    if rows:
        table = write_table(rows, cfg.eval_suites, out)
        print(table)
        results["table"] = table
    (out / "bench_planner.json").write_text(json.dumps(results, indent=2, default=str))


if __name__ == "__main__":
    main()
