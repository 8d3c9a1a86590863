"""The shipped recovering recipe trained on `full` (the training condition), evaluated on the held-out
protocol's suites (stock eval_policy in process, the study's evaluator).

    lerobot-pnp generate --repo_id local/baxter_pnp_full19 --root outputs/ds_full --num_episodes 1000 \
        --env.preset full
    python scripts/heldout_protocol_eval.py train RUN 300 [seed=N] [data=ROOT] [field=value ...]  # epochs; PnpLstmConfig overrides
    python scripts/heldout_protocol_eval.py eval RUN 100 [suite,suite,...|all] [field=value ...]
        # -> outputs/RUN/eval.json, or eval_<field=value...>.json with inference-time policy fields set (_nN when
        # N is not 200; an unknown field is an error);
        # env.<field>=value sets a task field on top of the suite (e.g. env.keyframe_budget=60, a diagnosis);
        # eval_seed=N starts the eval seeds at N (default 10,000,000; the study uses 100000)

RUN names the output folder outputs/RUN (the shipped recipe: no overrides); max_episode_length 41 as
configs/dagger.json. Overrides are JSON values, e.g. latency_augment_stretch=true latency_augment_jitter=0.5.
"""

import json
import sys
import time
from collections import Counter
from pathlib import Path

import protocol_runs  # scripts/: the protocol runs on disk

from lerobot_pnp.cache import CHECKPOINT_FILES, code_versions, digest_files, key_of
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.checkpoints import load_policy
from lerobot_pnp.evaluation.closed_loop import eval_lerobot_policy
from lerobot_pnp.evaluation.records import summarize
from lerobot_pnp.evaluation.stats import wilson_interval
from lerobot_pnp.policy.configuration_pnp_lstm import PnpLstmConfig
from lerobot_pnp.policy.recipes import RECOVERING_RECIPE
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.suites import HELD_OUT_AXES, SUITES

root, out = protocol_runs.TASK_ROOT, protocol_runs.run_dir(sys.argv[2])
if data := [a for a in sys.argv if a.startswith("data=")]:  # another dataset of the full task (train only)
    sys.argv.remove(data[0])
    root = Path(data[0].split("=", 1)[1])
stage = sys.argv[1]
if stage == "train":
    from lerobot_pnp.train_fast import TrainFastConfig, train_fast

    overrides = {k: json.loads(v) for k, v in (a.split("=", 1) for a in sys.argv[4:])}
    seed = int(overrides.pop("seed", 0))  # the training seed
    policy = PnpLstmConfig(
        **{**RECOVERING_RECIPE, **overrides},
        max_episode_length=41,
        subtask_loss_weight=0.1,
        phase_loss_weight=0.1,
        device="cpu",
        push_to_hub=False,
    )
    t = time.time()
    res = train_fast(
        TrainFastConfig(
            dataset_repo_id="local/baxter_pnp_full19",
            dataset_root=str(root),
            policy=policy,
            epochs=int(sys.argv[3]),
            batch_size=32,
            seed=seed,
            output_dir=str(out / "train"),
            overwrite=True,
            progress=False,
        )
    )
    (out / "train_done.json").write_text(
        json.dumps(
            {
                **res.summary(),
                "overrides": overrides,
                "seed": seed,
                "checkpoint": str(res.checkpoint_dir),
                "wall_s": time.time() - t,
            },
            indent=2,
            default=str,
        )
    )
else:
    ckpt = protocol_runs.checkpoint(sys.argv[2])
    n = int(sys.argv[3])
    names = ["nominal"] + list(dict.fromkeys(x for a in HELD_OUT_AXES for x in (*a.in_distribution, *a.held_out)))
    if len(sys.argv) > 4 and sys.argv[4] != "all":
        names = sys.argv[4].split(",")
    # Inference-time policy fields (e.g. await_observation=true) set on the loaded checkpoint's config.
    overrides = {k: json.loads(v) for k, v in (a.split("=", 1) for a in sys.argv[5:])}
    eval_seed = int(overrides.pop("eval_seed", 10_000_000))  # the first eval seed (the study's: 100000)
    env_changes = {k.removeprefix("env."): v for k, v in overrides.items() if k.startswith("env.")}
    try:
        base = BaxterPnPEnvConfig.from_source(str(root), **env_changes)
    except (TypeError, ConfigError) as e:  # an unknown or invalid task field: one line, not a traceback
        sys.exit(f"heldout_protocol_eval.py: env overrides {env_changes}: {e}")
    result_file = out / (
        "eval.json" if not overrides else "eval_" + "_".join(f"{k}={v}" for k, v in overrides.items()) + ".json"
    )
    if eval_seed != 10_000_000:
        result_file = result_file.with_name(f"{result_file.stem}_seed{eval_seed}.json")
    if n != 200:  # the protocol's count keeps the plain name; another count gets its own file, not an overwrite
        result_file = result_file.with_name(f"{result_file.stem}_n{n}.json")
    unknown = sorted(k for k in overrides if not k.startswith("env.") and k not in PnpLstmConfig.__dataclass_fields__)
    if unknown:  # setattr would take any name and change nothing
        sys.exit(f"heldout_protocol_eval.py: unknown policy field(s) {unknown}: see PnpLstmConfig")
    # A suite's result is reused only when its key matches: this checkpoint's content, the suite's env config
    # as the code builds it now, the episode count, the eval seed, the policy overrides, the batch and the
    # code versions (the file name holds the overrides, the eval seed and a count other than 200 too, so
    # variants do not overwrite each other); a result without a key (an older one) is redone.
    ckpt_digest = digest_files(ckpt, CHECKPOINT_FILES)
    results = json.loads(result_file.read_text()) if result_file.is_file() else {}
    batch, versions = 10, code_versions()
    for name in names:
        cfg = SUITES[name].env_configs(base)[0]
        key = key_of({"checkpoint": ckpt_digest, "env": cfg.to_dict(), "n": n, "eval_seed": eval_seed,
                      "overrides": overrides, "batch": batch, "versions": versions})  # fmt: skip
        if results.get(name, {}).get("key") == key:
            continue
        lp = load_policy(ckpt, env_cfg=cfg)
        policy, pre, post = lp.policy, lp.preprocessor, lp.postprocessor
        for k, v in overrides.items():
            if not k.startswith("env."):
                setattr(policy.config, k, v)
        policy.reset()
        t = time.time()
        recs = eval_lerobot_policy(policy, pre, post, cfg, n, eval_seed, batch)
        k = sum(r.success for r in recs)
        lo, hi = wilson_interval(k, n)
        causes = summarize(recs)["by_cause"]
        at_steps = dict(Counter(str(r.steps) for r in recs if not r.success))  # the step each failure ended at
        by_events = {}  # by the disturbances the episode drew: [successes, failures]
        for r in recs:
            events = "+".join(sorted(set((r.perturbations or "none").split(","))))
            by_events.setdefault(events, [0, 0])[0 if r.success else 1] += 1
        results[name] = {
            "successes": k,
            "n": n,
            "wilson95": [lo, hi],
            "failures": causes,
            "failures_at_step": at_steps,
            "by_disturbances": {e: {"successes": v[0], "failures": v[1]} for e, v in by_events.items()},
            "mean_steps_success": sum(r.steps for r in recs if r.success) / max(k, 1),
            "wall_s": time.time() - t,
            "checkpoint_digest": ckpt_digest,
            "key": key,
        }
        print(
            f"{name:<26} {k}/{n} = {100 * k / n:5.1f} % [{100 * lo:5.1f}, {100 * hi:5.1f}] {causes} {time.time() - t:.0f}s",
            flush=True,
        )
        result_file.write_text(json.dumps(results, indent=2))
