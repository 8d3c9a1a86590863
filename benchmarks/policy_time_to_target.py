"""Sections a and b of ``bench_policy.py``: time to target on the fast path and with stock ``lerobot-train``
(see that module's docstring for what is measured)."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

from policy_runs import EVAL_SEED, checkpoints, lerobot_eval_success, log, rollout_success, train


# ---------------------------------------------------------------------------------------------- a
def bench_time_to_target(args, dataset, work: Path) -> dict:
    log(f"\n=== a. fast path: time to {args.target:.0f}% closed-loop success ===")
    run_dir = work / "fast_recurrent"
    result, start_wall, total_s = train(
        dataset, run_dir, epochs=args.epochs, save_every_epochs=args.ckpt_every, seed=args.seed
    )
    epoch_of_step = {h["step"]: h["epoch"] for h in result.history}
    loop_time_of_step = {h["step"]: h["time_s"] for h in result.history}
    log(
        f"trained {args.epochs} epochs ({result.steps} steps) in {total_s:.1f} s; "
        f"final test MSE {result.final_test_mse:.3g}"
    )
    curve, reached, n_confirms = [], None, 0
    for step, ckpt in checkpoints(run_dir):
        wall = (ckpt / "model.safetensors").stat().st_mtime - start_wall
        is_last = step == result.steps
        if reached is not None and not is_last:
            continue  # after the target: only the final checkpoint is still evaluated
        ev = rollout_success(ckpt, args.curve_episodes)
        point = {
            "epoch": epoch_of_step.get(step),
            "step": step,
            "wall_s_since_start": wall,
            "train_loop_s": loop_time_of_step.get(step),
            "pc_success": ev["pc_success"],
            "n_episodes": ev["n_episodes"],
            "eval_s": ev["eval_s"],
            "checkpoint": str(ckpt),
        }
        curve.append(point)
        log(
            f"  epoch {point['epoch']:>4} step {step:>5}  wall {wall:6.1f} s  success {ev['pc_success']:5.1f}% "
            f"({ev['n_episodes']} ep, eval {ev['eval_s']:.1f} s)"
        )
        if reached is None and ev["pc_success"] >= args.target:
            if args.confirm_episodes > 0 and n_confirms < 3:
                # Re-check with the real lerobot-eval on more episodes; only a confirmed checkpoint counts.
                n_confirms += 1
                conf = lerobot_eval_success(ckpt, work / f"confirm_{step}", args.confirm_episodes)
                point["confirm_lerobot_eval"] = conf
                log(
                    f"    lerobot-eval check: {conf['pc_success']:.1f}% over {conf['n_episodes']} episodes "
                    f"({conf['eval_s']:.0f} s)"
                )
                if conf["pc_success"] < args.target:
                    continue
            reached = point
    out = {
        "eval_method": f"in-process closed_loop.run_episode on {args.curve_episodes} unseen seeds "
        f"{EVAL_SEED}..{EVAL_SEED + args.curve_episodes - 1}",
        "epochs": args.epochs,
        "ckpt_every_epochs": args.ckpt_every,
        "train_total_s": total_s,
        "final_test_mse": result.final_test_mse,
        "curve": curve,
        "target_pc": args.target,
        "time_to_target_s": reached["wall_s_since_start"] if reached else None,
        "epoch_at_target": reached["epoch"] if reached else None,
        "final_checkpoint": str(result.checkpoint_dir),
    }
    out["target_rule"] = f"first checkpoint with >= {args.target:.0f}% on the rollouts" + (
        f" and on a {args.confirm_episodes}-episode lerobot-eval check (at most 3 checks)"
        if args.confirm_episodes > 0
        else ""
    )
    return out


# ---------------------------------------------------------------------------------------------- b
_LOG_RE = re.compile(r"updt_s:([0-9.]+).*data_s:([0-9.]+)")
_CKPT_RE = re.compile(r"Checkpoint policy after step (\d+)")
_EVAL_RE = re.compile(r"Eval policy at step (\d+)")
_SUCCESS_RE = re.compile(r"Suite overall aggregated: .*'pc_success': ([0-9.]+)")


def bench_stock_time_to_target(args, dataset, work: Path) -> dict:
    """Stock ``lerobot-train --config_path configs/train_pnp_lstm.json``, as a user runs it.

    Only the dataset root and the output folder are overridden. Time to target = process start to the
    checkpoint of the first step whose in-training env eval reaches the target (eval time excluded, as in a);
    that checkpoint is then confirmed with the real ``lerobot-eval`` on ``--confirm_episodes`` episodes.
    """
    log(f"\n=== b. stock lerobot-train --config_path {args.train_config}: time to {args.target:.0f}% ===")
    out_dir = work / "lerobot_train"
    if out_dir.exists():
        shutil.rmtree(out_dir)
    cmd = [
        str(Path(sys.executable).with_name("lerobot-train")),
        f"--config_path={args.train_config}",
        f"--dataset.root={dataset[1]}",
        f"--dataset.repo_id={dataset[0]}",
        f"--output_dir={out_dir}",
    ]
    log(" ".join(cmd))
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"}
    )
    t_start_loop = t_end_loop = None
    updt = data = None
    ckpt_time: dict[int, float] = {}
    evals: list[dict] = []
    eval_step = None
    tail: list[str] = []
    assert proc.stdout is not None
    for line in proc.stdout:
        now = time.perf_counter() - t0
        tail = (tail + [line])[-40:]
        if t_start_loop is None and "Start offline training" in line:
            t_start_loop = now
        if "End of training" in line:
            t_end_loop = now
        if m := _LOG_RE.search(line):
            updt, data = float(m.group(1)), float(m.group(2))
        if m := _CKPT_RE.search(line):
            ckpt_time[int(m.group(1))] = now
        if m := _EVAL_RE.search(line):
            eval_step = int(m.group(1))
        if (m := _SUCCESS_RE.search(line)) and eval_step is not None:
            evals.append({"step": eval_step, "pc_success": float(m.group(1)), "logged_at_s": now})
            log(f"  in-training eval at step {eval_step}: {float(m.group(1)):.1f}% (t = {now:.0f} s)")
    rc = proc.wait()
    total = time.perf_counter() - t0
    if rc != 0:
        raise RuntimeError(f"lerobot-train failed ({rc}):\n{''.join(tail)}")
    train_cfg = json.loads(Path(args.train_config).read_text())
    reached = next((e for e in evals if e["pc_success"] >= args.target), None)
    res = {
        "command": " ".join(cmd),
        "steps": train_cfg["steps"],
        "batch_size": train_cfg["batch_size"],
        "num_workers": train_cfg["num_workers"],
        "wall_s": total,
        "startup_s": t_start_loop,
        "loop_s": (t_end_loop or total) - (t_start_loop or 0),
        "last_log_updt_s": updt,
        "last_log_data_s": data,
        "in_training_evals": evals,
        "time_to_target_s": ckpt_time.get(reached["step"]) if reached else None,
        "step_at_target": reached["step"] if reached else None,
    }
    if reached and args.confirm_episodes > 0:
        ckpt = out_dir / "checkpoints" / f"{reached['step']:06d}" / "pretrained_model"
        conf = lerobot_eval_success(ckpt, work / "confirm_stock", args.confirm_episodes)
        res["confirm_lerobot_eval"] = conf
        log(f"    lerobot-eval check: {conf['pc_success']:.1f}% over {conf['n_episodes']} episodes")
    log(
        f"  lerobot-train: {total:.1f} s total (start-up {t_start_loop or float('nan'):.1f} s, loop "
        f"{res['loop_s']:.1f} s, last log updt_s {updt} data_s {data}); time to target: "
        + (f"{res['time_to_target_s']:.1f} s (step {reached['step']})" if reached else "NOT reached")
    )
    return res
