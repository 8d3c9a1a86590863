"""Policy benchmarks, measured side by side in one run.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_policy.py [--quick] [--out outputs/bench_policy.json]

a. Time to target (fast path): ``train_fast`` on the keyframe dataset with a checkpoint every
   ``--ckpt_every`` epochs; each checkpoint is rolled out closed loop in-process with
   ``lerobot_pnp.closed_loop.run_episode`` (the same pipeline as ``lerobot-eval``: preprocess_observation
   -> pre-processor -> select_action -> post-processor -> env.step) on ``--curve_episodes`` unseen seeds
   (100000 + i; the dataset uses seeds < 20000). "Wall time to target" = from calling ``train_fast`` (dataset
   load included) to the checkpoint file of the first checkpoint whose success >= ``--target`` %; the
   evaluation time is not included (it is printed separately). In full mode that checkpoint is re-checked
   with the real ``lerobot-eval`` (``demo.run_eval``) on ``--confirm_episodes`` episodes.
b. Time to target (stock path): ``lerobot-train --config_path configs/train_pnp_lstm.json`` as a user runs
   it (only the dataset root and output folder overridden); its own in-training env eval decides, the
   checkpoint that reached the target is confirmed with ``lerobot-eval``. Printed next to a.
c. ``select_action`` latency (mean and median) of pnp_lstm at batch 1 and 50 next to LeRobot's ACT (default config, built on
   the same features: observation.state 8, observation.environment_state 3, action 8). pnp_lstm: mean per
   call over whole 10-step episodes (reset every 10 calls, so every call runs the LSTM). ACT: per model call
   (first select_action after reset, which computes the 100-step chunk) and per step amortised over a full
   chunk (100 select_action calls / 100). One torch thread for both, as everything here.
   ``--sections c --checkpoint DIR`` times an existing checkpoint alone (e.g. one written before a change).
   Beside them, at batch 1 on pre-rendered 64x64 front and wrist images (the env's rendering excluded): the
   camera planner ``pnp_pixels`` and image ACT, each with its shipped config's architecture.
d. Memory and feedback: the default recurrent policy vs the memoryless variant (``recurrent=False``, trained
   the same way) under nominal / nudge 3 cm / noise (object 5 mm, joints 0.01 rad) / all together;
   ``--robust_episodes`` episodes each, in-process rollouts (``--robust_backend lerobot-eval`` runs the real
   ``lerobot-eval`` instead).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MUJOCO_GL", "egl")

import torch

torch.set_num_threads(1)

from policy_runs import lerobot_eval_success, log, rollout_success, train  # noqa: E402
from policy_time_to_target import bench_stock_time_to_target, bench_time_to_target  # noqa: E402

from lerobot_pnp.dataset.layout import is_dataset  # noqa: E402

CONDITIONS = {
    "nominal": {},
    "nudge_3cm": {"nudge_max": 0.03},
    "noise": {"obs_noise_object": 0.005, "obs_noise_joints": 0.01},
    "all": {"nudge_max": 0.03, "obs_noise_object": 0.005, "obs_noise_joints": 0.01},
}


# ---------------------------------------------------------------------------------------------- c
def _time_calls(fn, n: int) -> list[float]:
    out = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def _ms(xs: list[float]) -> dict:
    return {"mean_ms": 1e3 * statistics.fmean(xs), "median_ms": 1e3 * statistics.median(xs)}


@torch.inference_mode()
def bench_latency(args, ckpt: Path) -> dict:
    from lerobot.configs import FeatureType, PolicyFeature
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.act.modeling_act import ACTPolicy

    from lerobot_pnp.evaluation.checkpoints import load_policy

    log("\n=== c. select_action latency (CPU, 1 torch thread) ===")
    loaded = load_policy(ckpt)
    pol = loaded.policy
    reps = args.latency_reps
    res: dict = {"pnp_lstm": {"params": sum(p.numel() for p in pol.parameters())}, "act": {}}
    env_dim = int(pol.config.input_features["observation.environment_state"].shape[0])  # 3 (paper) or 7 (full)
    for bsz in (1, 50):
        batch = {"observation.state": torch.randn(bsz, 8), "observation.environment_state": torch.randn(bsz, env_dim)}
        for _ in range(3):  # warm-up
            pol.reset()
            pol.select_action(batch)
        times = []
        for _ in range(reps):
            pol.reset()
            times += _time_calls(lambda batch=batch: pol.select_action(batch), 10)
        res["pnp_lstm"][f"b{bsz}"] = _ms(times)
        # The whole step as lerobot-eval runs it: pre-processor + select_action + post-processor.
        raw = {
            "observation.state": torch.randn(bsz, 8),
            "observation.environment_state": torch.randn(bsz, env_dim),
            "task": ["pick"] * bsz,
        }

        def full_step(raw=raw):
            loaded.postprocessor(pol.select_action(loaded.preprocessor(dict(raw))))

        times = []
        for _ in range(reps):
            pol.reset()
            times += _time_calls(full_step, 10)
        res["pnp_lstm"][f"b{bsz}_with_processors"] = _ms(times)

    cfg = ACTConfig(device="cpu")
    cfg.input_features = {
        "observation.state": PolicyFeature(FeatureType.STATE, (8,)),
        "observation.environment_state": PolicyFeature(FeatureType.ENV, (3,)),
    }
    cfg.output_features = {"action": PolicyFeature(FeatureType.ACTION, (8,))}
    act = ACTPolicy(cfg).eval()
    res["act"]["params"] = sum(p.numel() for p in act.parameters())
    res["act"]["chunk_size"] = cfg.chunk_size
    res["act"]["n_action_steps"] = cfg.n_action_steps
    for bsz in (1, 50):
        batch = {"observation.state": torch.randn(bsz, 8), "observation.environment_state": torch.randn(bsz, 3)}
        act.reset()
        act.select_action(batch)  # warm-up
        calls = []
        for _ in range(max(3, reps // 4)):
            act.reset()
            calls += _time_calls(lambda batch=batch: act.select_action(batch), 1)
        res["act"][f"b{bsz}_per_model_call"] = _ms(calls)
        chunk = []
        for _ in range(max(1, reps // 20)):
            act.reset()
            t = time.perf_counter()
            for _ in range(cfg.n_action_steps):
                act.select_action(batch)
            chunk.append((time.perf_counter() - t) / cfg.n_action_steps)
        res["act"][f"b{bsz}_per_step_amortised"] = _ms(chunk)
    res |= bench_image_latency(reps)
    for name in res:
        r = res[name]
        log(
            f"  {name:9s} ({r['params'] / 1e6:.3f} M params): "
            + ", ".join(f"{k} {v['mean_ms']:.3f} ms" for k, v in r.items() if isinstance(v, dict))
        )
    return res


IMAGE_FEATURES = {"observation.images.front": (3, 64, 64), "observation.images.wrist": (3, 64, 64)}


def _shipped(config: str, cls, drop=("type", "input_features")):
    """A policy built from a shipped ``configs/`` file's policy fields, on joints + the two 64x64 cameras."""
    from lerobot.configs import FeatureType, PolicyFeature

    fields = json.loads((Path(__file__).resolve().parents[1] / "configs" / config).read_text())["policy"]
    cfg = cls(**{k: v for k, v in fields.items() if k not in drop})
    cfg.input_features = {"observation.state": PolicyFeature(FeatureType.STATE, (8,))} | {
        k: PolicyFeature(FeatureType.VISUAL, shape) for k, shape in IMAGE_FEATURES.items()
    }
    cfg.output_features = {"action": PolicyFeature(FeatureType.ACTION, (8,))}
    return cfg


@torch.inference_mode()
def bench_image_latency(reps: int) -> dict:
    """``select_action`` at batch 1 of the camera planner and of image ACT (the shipped configs' architectures,
    untrained: the cost does not depend on the weights) on pre-rendered 64x64 front and wrist images, so the
    env's rendering is not in it; per call over whole 15-keyframe episodes, a reset between episodes. Image ACT
    runs one model call per step (``n_action_steps`` 1, as the keyframe recipe uses it)."""
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.act.modeling_act import ACTPolicy

    from lerobot_pnp.policy.configuration_pnp_pixels import PnpPixelsConfig
    from lerobot_pnp.policy.modeling_pnp_pixels import PnpPixelsPolicy

    policies = {
        "pnp_pixels": PnpPixelsPolicy(_shipped("train_pnp_pixels.json", PnpPixelsConfig)),
        "act_images": ACTPolicy(_shipped("train_act_images.json", ACTConfig)),
    }
    batch = {"observation.state": torch.randn(1, 8)} | {k: torch.rand(1, *s) for k, s in IMAGE_FEATURES.items()}
    res = {}
    for name, pol in policies.items():
        pol.eval()
        pol.reset()
        pol.select_action(dict(batch))  # warm-up
        times = []
        for _ in range(max(3, reps // 10)):
            pol.reset()
            times += _time_calls(lambda pol=pol: pol.select_action(dict(batch)), 15)
        res[name] = {"params": sum(p.numel() for p in pol.parameters()), "b1": _ms(times)}
    return res


# ---------------------------------------------------------------------------------------------- d
def bench_memory_feedback(args, dataset, work: Path, recurrent_ckpt: Path) -> dict:
    log(f"\n=== d. memory and feedback: recurrent vs memoryless, {args.robust_episodes} episodes each ===")
    result, _, t = train(
        dataset, work / "fast_memoryless", epochs=args.epochs, seed=args.seed, policy={"recurrent": False}
    )
    log(f"  memoryless variant trained {args.epochs} epochs in {t:.1f} s (final test MSE {result.final_test_mse:.3g})")
    models = {"recurrent": recurrent_ckpt, "memoryless": result.checkpoint_dir}
    table: dict = {
        "eval_method": args.robust_backend,
        "n_episodes": args.robust_episodes,
        "conditions": CONDITIONS,
        "memoryless_final_test_mse": result.final_test_mse,
        "success": {},
    }
    for model, ckpt in models.items():
        table["success"][model] = {}
        for cond, env_args in CONDITIONS.items():
            if args.robust_backend == "lerobot-eval":
                ev = lerobot_eval_success(ckpt, work / f"eval_{model}_{cond}", args.robust_episodes, env_args)
            else:
                ev = rollout_success(ckpt, args.robust_episodes, env_args)
            table["success"][model][cond] = ev["pc_success"]
            log(f"  {model:10s} {cond:10s} {ev['pc_success']:5.1f}%  ({ev['eval_s']:.1f} s)")
    return table


# ---------------------------------------------------------------------------------------------- main
def args_target(res: dict) -> float:
    return float(res["args"]["target"])


def print_summary(res: dict) -> None:
    log("\n" + "=" * 78 + "\nSUMMARY (2-core CPU, 1 torch thread)\n" + "=" * 78)
    a = res.get("a")
    if a:
        tt = a["time_to_target_s"]
        log(
            f"a. fast path to >= {a['target_pc']:.0f}% success: "
            + (f"{tt:.1f} s (epoch {a['epoch_at_target']})" if tt is not None else "NOT reached")
            + f"   [{a['eval_method']}]"
        )
        log(f"   rule: {a['target_rule']}")
        log("   epoch | wall s | success % | lerobot-eval check %")
        for p in a["curve"]:
            c = p.get("confirm_lerobot_eval")
            log(
                f"   {p['epoch']:>5} | {p['wall_s_since_start']:6.1f} | {p['pc_success']:9.1f} | "
                + (f"{c['pc_success']:.1f} ({c['n_episodes']} ep)" if c else "-")
            )
    b = res.get("b")
    if b:
        tt = b["time_to_target_s"]
        conf = b.get("confirm_lerobot_eval")
        log(
            f"b. stock lerobot-train to >= {args_target(res):.0f}% success: "
            + (f"{tt:.1f} s (step {b['step_at_target']})" if tt is not None else "NOT reached")
            + (f"; lerobot-eval check {conf['pc_success']:.1f}% ({conf['n_episodes']} ep)" if conf else "")
        )
        log(
            f"   {b['steps']} steps x batch {b['batch_size']}, {b['num_workers']} loader workers: wall {b['wall_s']:.1f} s "
            f"(start-up {b['startup_s'] or float('nan'):.1f} s, loop {b['loop_s']:.1f} s); in-training evals "
            + ", ".join(f"step {e['step']}: {e['pc_success']:.1f}%" for e in b["in_training_evals"])
        )
        if a and a["time_to_target_s"] and tt:
            log(
                f"   time to target, stock / fast path: {tt:.1f} s / {a['time_to_target_s']:.1f} s = {tt / a['time_to_target_s']:.1f}x"
            )
    c = res.get("c")
    if c:
        p, q = c["pnp_lstm"], c["act"]
        log("c. select_action, mean ms     |   batch 1 |  batch 50")
        log(f"   pnp_lstm per call          | {p['b1']['mean_ms']:9.3f} | {p['b50']['mean_ms']:9.3f}")
        log(f"   pnp_lstm per call (median) | {p['b1']['median_ms']:9.3f} | {p['b50']['median_ms']:9.3f}")
        log(
            f"   pnp_lstm + processors      | {p['b1_with_processors']['mean_ms']:9.3f} | "
            f"{p['b50_with_processors']['mean_ms']:9.3f}"
        )
        log(
            f"   ACT per model call         | {q['b1_per_model_call']['mean_ms']:9.3f} | "
            f"{q['b50_per_model_call']['mean_ms']:9.3f}"
        )
        log(
            f"   ACT per step (chunk {q['n_action_steps']:>3})    | {q['b1_per_step_amortised']['mean_ms']:9.3f} | "
            f"{q['b50_per_step_amortised']['mean_ms']:9.3f}"
        )
        log(f"   params: pnp_lstm {p['params']:,}, ACT {q['params']:,}")
    d = res.get("d")
    if d:
        log(f"d. success % ({d['n_episodes']} episodes each, {d['eval_method']})")
        log("   model      | " + " | ".join(f"{k:>9}" for k in CONDITIONS))
        for model, row in d["success"].items():
            log(f"   {model:10s} | " + " | ".join(f"{row[k]:9.1f}" for k in CONDITIONS))


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--dataset_root", default="outputs/demo/dataset")
    p.add_argument("--repo_id", default="local/baxter_pnp_keyframe")
    p.add_argument("--quick", action="store_true", help="small everything (a few minutes)")
    p.add_argument(
        "--sections", default="abcd", help="which of a, b, c, d to run (d needs a; c needs a or --checkpoint)"
    )
    p.add_argument("--epochs", type=int, default=None, help="fast-path epochs (default 300; quick 60)")
    p.add_argument("--ckpt_every", type=int, default=None, help="checkpoint every N epochs (default 5; quick 10)")
    p.add_argument("--curve_episodes", type=int, default=None, help="rollouts per checkpoint (100; quick 30)")
    p.add_argument(
        "--confirm_episodes",
        type=int,
        default=None,
        help="lerobot-eval episodes to confirm the target checkpoint (200; quick 0 = skip)",
    )
    p.add_argument("--train_config", default="configs/train_pnp_lstm.json", help="lerobot-train config for b")
    p.add_argument("--checkpoint", default=None, help="c without a: time this checkpoint")
    p.add_argument("--latency_reps", type=int, default=None, help="10-step episodes timed in c (200; quick 40)")
    p.add_argument("--robust_episodes", type=int, default=None, help="episodes per cell in d (200; quick 30)")
    p.add_argument("--robust_backend", choices=("rollout", "lerobot-eval"), default="rollout")
    p.add_argument("--target", type=float, default=98.0)
    p.add_argument("--seed", type=int, default=1000)
    p.add_argument("--workdir", default="outputs/bench_policy_work")
    p.add_argument("--out", default="outputs/bench_policy.json")
    args = p.parse_args(argv)
    quick = args.quick
    defaults = {
        "epochs": (300, 60),
        "ckpt_every": (5, 10),
        "curve_episodes": (100, 30),
        "confirm_episodes": (200, 0),
        "latency_reps": (200, 40),
        "robust_episodes": (200, 30),
    }
    for k, (full, small) in defaults.items():
        if getattr(args, k) is None:
            setattr(args, k, small if quick else full)
    root = Path(args.dataset_root)
    if args.sections != "c" and not is_dataset(root):
        p.error(f"no finished dataset at {root}: run `lerobot-pnp generate --root {root}` (or the demo) first")
    dataset = (args.repo_id, str(root))
    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    res: dict = {"args": vars(args), "torch_threads": torch.get_num_threads(), "cpu_count": os.cpu_count()}
    start = time.perf_counter()
    if "a" in args.sections:
        res["a"] = bench_time_to_target(args, dataset, work)
    final_ckpt = Path(res["a"]["final_checkpoint"]) if "a" in res else None
    if args.checkpoint:
        final_ckpt = Path(args.checkpoint)
    if "b" in args.sections:
        res["b"] = bench_stock_time_to_target(args, dataset, work)
    if "c" in args.sections and final_ckpt:
        res["c"] = bench_latency(args, final_ckpt)
    if "d" in args.sections and final_ckpt:
        res["d"] = bench_memory_feedback(args, dataset, work, final_ckpt)
    res["bench_wall_s"] = time.perf_counter() - start
    print_summary(res)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=2, default=str))
    log(f"\nnumbers: {out}  (bench wall {res['bench_wall_s']:.0f} s)")
    return res


if __name__ == "__main__":
    main()
