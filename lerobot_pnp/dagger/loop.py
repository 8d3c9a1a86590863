"""The DAgger rounds: demonstrations -> train -> (roll out, label, aggregate, retrain) x N, evaluated each round.

Retraining is **from scratch** on the aggregate each round: the normalisation statistics change with the
data (DAgger adds the policy's off-distribution states), a fresh policy is a function of its dataset and seed
only (deterministic, reproducible on its own), and the recovering planner trains in about a minute, so a warm
start would save little.

Layout of ``output_dir``::

    demos/                 round-0 expert demonstrations (LeRobotDataset), unless --base_root is given
    round_01/rollouts/     the round-1 policy rollouts labelled by the expert (LeRobotDataset)
    round_01/data/         demos + rollouts of rounds 1..r, merged with aggregate_datasets
    round_XX/train/        fast-path training run (checkpoints/last/pretrained_model)
    round_XX/eval.json     success per suite on the evaluation seeds
    table.md / table.json  success per round and suite with Wilson 95 % intervals

Every stage is keyed (``lerobot_pnp.cache``) by what determines it and recorded when complete: the datasets'
``stage.json``, ``round_XX/rollouts.json``, ``round_XX/train/done.json`` (the checkpoint relative to it) and
``round_XX/eval.stage.json``. A stage whose key changed (another seed, num_demos, round-0 checkpoint, ...) is
re-run, and so is everything keyed by it; the folder is locked for the run.
"""

from __future__ import annotations

import copy
import json
import logging
import time
from pathlib import Path

from lerobot_pnp.cache import (
    CHECKPOINT_FILES,
    DATASET_FILES,
    STAGE_FILE,
    Stage,
    code_versions,
    digest_files,
    key_of,
    lock_output,
    remove,
    same_env_configs,
    write_json_atomic,
)
from lerobot_pnp.evaluation.checkpoints import load_policy
from lerobot_pnp.evaluation.stats import Rate

from .config import DaggerConfig
from .rollouts import evaluate, expert_episode, labelled_rollout, suite_env
from .writer import aggregate, write_episodes

logger = logging.getLogger(__name__)
ROUND_SEED_STRIDE = 1_000_000
ROLLOUT_SUMMARY = ("episodes", "frames", "policy_successes")  # in rollouts.json, beside the stage's key


def _tqdm(total: int, desc: str, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, disable=not enabled, leave=False)


def base_env_config(cfg: DaggerConfig):
    """The task DAgger runs on: ``base_root``'s recorded task, or the preset, with ``env_changes`` applied."""
    from lerobot_pnp.env_config import BaxterPnPEnvConfig

    if cfg.base_root:
        return BaxterPnPEnvConfig(task_source=cfg.base_root, **cfg.env_changes)
    return BaxterPnPEnvConfig(preset=cfg.preset, **cfg.env_changes)


def _stage(record: Path, what: str, **parts) -> Stage:
    """A DAgger stage keyed by ``parts`` and the code versions (see ``lerobot_pnp.cache``)."""
    return Stage(record, {"stage": what, **parts, "versions": code_versions()}, compare={"env": same_env_configs})


def _key(what: str, **parts) -> str:
    """The key of an input no stage of this run produced (a dataset or checkpoint passed in): its content."""
    return key_of({"stage": what, **parts, "versions": code_versions()})


def _demos(cfg: DaggerConfig, out: Path, env_cfg) -> tuple[Path, str, str, str]:
    """(root, repo_id, test range, key) of the round-0 data, written once per key."""
    if cfg.base_root:
        from lerobot.datasets.io_utils import load_info

        info = load_info(Path(cfg.base_root))
        n = int(info.total_episodes)
        test = (info.splits or {}).get("test") or f"{n - max(1, round(cfg.test_fraction * n))}:{n}"
        key = _key("base", content=digest_files(Path(cfg.base_root), DATASET_FILES), test=test)
        return Path(cfg.base_root), cfg.base_repo_id, test, key
    root, repo_id = out / "demos", f"{cfg.base_repo_id}_demos"
    n = cfg.num_demos
    test = f"{n - max(1, round(cfg.test_fraction * n))}:{n}"
    stage = _stage(root / STAGE_FILE, "demos", env=env_cfg.to_dict(), num_demos=n, test=test, seed=cfg.seed,
                   repo_id=repo_id)  # fmt: skip
    if not stage.done("dagger demos"):
        stage.invalidate()
        env = suite_env(env_cfg, "nominal")  # the task as recorded (DAgger's former "full")
        episodes, seed = [], cfg.seed
        with _tqdm(n, "expert demos", cfg.progress) as bar:
            while len(episodes) < n:
                ep = expert_episode(env, seed, "full")
                seed += 1
                if ep is not None:
                    episodes.append(ep)
                    bar.update(1)
        env.close()
        write_episodes(root, repo_id, env_cfg, episodes, {"test": test})
        stage.commit()
    return root, repo_id, test, stage.key


def _rollouts(cfg: DaggerConfig, rnd: int, ckpt: tuple[Path, str], out: Path, env_cfg) -> tuple[Path, str, dict, str]:
    """Round ``rnd``'s expert-labelled rollouts of the checkpoint ``ckpt`` (its path and key)."""
    root, repo_id = out / f"round_{rnd:02d}" / "rollouts", f"{cfg.base_repo_id}_dagger{rnd:02d}"
    stage = _stage(root.parent / "rollouts.json", "rollouts", policy=ckpt[1], env=env_cfg.to_dict(),
                   episodes=cfg.rollouts_per_round, suites=cfg.rollout_suites, seed=cfg.seed + ROUND_SEED_STRIDE * rnd,
                   repo_id=repo_id)  # fmt: skip
    if stage.done(f"dagger round {rnd} rollouts"):
        return root, repo_id, {k: stage.stored()[k] for k in ROLLOUT_SUMMARY}, stage.key
    stage.invalidate()
    policy = load_policy(ckpt[0])
    envs = {s: suite_env(env_cfg, s) for s in cfg.rollout_suites}
    episodes = []
    with _tqdm(cfg.rollouts_per_round, f"round {rnd} rollouts", cfg.progress) as bar:
        for i in range(cfg.rollouts_per_round):
            suite = cfg.rollout_suites[i % len(cfg.rollout_suites)]
            seed = cfg.seed + ROUND_SEED_STRIDE * rnd + i
            episodes.append(labelled_rollout(envs[suite], policy, seed, suite))
            bar.update(1)
    for env in envs.values():
        env.close()
    write_episodes(root, repo_id, env_cfg, episodes)
    counts = (len(episodes), int(sum(len(e.actions) for e in episodes)), int(sum(e.success for e in episodes)))
    summary = dict(zip(ROLLOUT_SUMMARY, counts, strict=True))
    stage.commit(**summary)
    return root, repo_id, summary, stage.key


def _aggregate(inputs: list[tuple[Path, str, str]], data_root: Path, repo_id: str, env_cfg, test: str) -> str:
    """The merge of ``inputs`` ((root, repo_id, key) each) into ``data_root``, rebuilt when an input changed."""
    stage = _stage(data_root / STAGE_FILE, "aggregate", inputs=[k for _, _, k in inputs], test=test,
                   repo_id=repo_id)  # fmt: skip
    if not stage.done(f"dagger {data_root.parent.name} aggregate"):
        stage.invalidate()
        aggregate([r for r, _, _ in inputs], [i for _, i, _ in inputs], data_root, repo_id, env_cfg, {"test": test})
        stage.commit()
    return stage.key


def _train(cfg: DaggerConfig, data: tuple[Path, str, str], test: str, out_dir: Path) -> tuple[Path, str]:
    """Train on ``data`` (root, repo_id, key); the checkpoint (its path and key). ``done.json`` records the
    checkpoint relative to the training folder, so a moved output folder reads its own checkpoint."""
    import draccus

    from lerobot_pnp.train_fast import TrainFastConfig, train_fast

    root, repo_id, data_key = data
    stage = _stage(out_dir / "done.json", "train", data=data_key, test=test, policy=draccus.encode(cfg.policy),
                   epochs=cfg.epochs, batch_size=cfg.batch_size, seed=cfg.seed)  # fmt: skip
    if stage.done(f"dagger {out_dir.parent.name} training"):
        return out_dir / stage.stored()["checkpoint"], stage.key
    stage.invalidate()  # a training killed midway leaves no record that a later run could match
    result = train_fast(
        TrainFastConfig(
            dataset_repo_id=repo_id,
            dataset_root=str(root),
            policy=copy.deepcopy(cfg.policy),
            epochs=cfg.epochs,
            batch_size=cfg.batch_size,
            seed=cfg.seed,
            output_dir=str(out_dir),
            overwrite=True,
            test_episodes=test,
            progress=cfg.progress,
        )
    )
    summary = {k: v for k, v in result.summary().items() if k not in ("checkpoint", "output_dir")}
    stage.commit(**summary, checkpoint=str(Path(result.checkpoint_dir).resolve().relative_to(out_dir.resolve())))
    return Path(result.checkpoint_dir), stage.key


def checkpoint_key(ckpt: Path) -> str:
    """The key of a checkpoint passed in by path: its content (config, weights, processors, task)."""
    return _key("checkpoint", content=digest_files(Path(ckpt), CHECKPOINT_FILES))


def evaluate_checkpoint(cfg: DaggerConfig, ckpt: Path, env_cfg, out_file: Path, ckpt_key: str | None = None) -> dict:
    """Success per eval suite on seeds ``eval_seed + i`` (the same for every round); cached in ``out_file``
    (its record ``<name>.stage.json`` keys it by the checkpoint, the env and the evaluation settings)."""
    stage = _stage(out_file.with_suffix(".stage.json"), "eval", policy=ckpt_key or checkpoint_key(ckpt),
                   env=env_cfg.to_dict(), suites=cfg.eval_suites, episodes=cfg.eval_episodes,
                   eval_seed=cfg.eval_seed)  # fmt: skip
    if out_file.is_file() and stage.done(f"dagger {out_file.parent.name} evaluation"):
        return json.loads(out_file.read_text())
    stage.invalidate()
    policy = load_policy(ckpt)
    seeds = [cfg.eval_seed + i for i in range(cfg.eval_episodes)]
    results = {}
    with _tqdm(len(seeds) * len(cfg.eval_suites), f"eval {out_file.parent.name}", cfg.progress) as bar:
        for suite in cfg.eval_suites:
            results[suite] = evaluate(policy, env_cfg, suite, seeds, bar)
    write_json_atomic(out_file, results)
    stage.commit()
    return results


def write_table(rows: list[tuple[str, dict]], suites: list[str], out: Path) -> str:
    """Markdown table: one row per policy, success and Wilson 95 % interval per suite."""
    lines = ["| policy | " + " | ".join(suites) + " |", "|---" * (len(suites) + 1) + "|"]
    data = []
    for name, res in rows:
        rates = {s: Rate(res[s]["successes"], res[s]["n"]) for s in suites if s in res}
        cells = [str(rates[s]) if s in rates else "-" for s in suites]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
        data.append(
            {"policy": name, **{s: {**res[s], "rate": r.rate, "wilson95": r.interval} for s, r in rates.items()}}
        )
    table = "\n".join(lines) + "\n"
    (out / "table.md").write_text(table)
    (out / "table.json").write_text(json.dumps(data, indent=2))
    return table


def run_dagger(cfg: DaggerConfig) -> dict:
    """``lerobot-pnp dagger``: see ``DaggerConfig`` and the module docstring. Returns the summary table.

    The output folder is locked for the whole run (a second run on it fails at once)."""
    out = Path(cfg.output_dir)
    with lock_output(out, "lerobot-pnp dagger"):
        return _run_rounds(cfg, out)


def _run_rounds(cfg: DaggerConfig, out: Path) -> dict:
    import torch

    torch.set_num_threads(1)
    env_cfg = base_env_config(cfg)
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    demo_root, demo_repo, test, demo_key = _demos(cfg, out, env_cfg)
    timings["demos_s"] = time.perf_counter() - t0

    rows, inputs = [], [(demo_root, demo_repo, demo_key)]
    data = (demo_root, demo_repo, demo_key)
    ckpt = None
    rollout_summaries = {}
    for rnd in range(cfg.rounds + 1):
        rdir = out / f"round_{rnd:02d}"
        rdir.mkdir(exist_ok=True)
        t = time.perf_counter()
        if rnd > 0:
            root, repo, summary, key = _rollouts(cfg, rnd, ckpt, out, env_cfg)
            rollout_summaries[rnd] = summary
            inputs.append((root, repo, key))
            data_root, data_repo = rdir / "data", f"{cfg.base_repo_id}_aggregate{rnd:02d}"
            data = (data_root, data_repo, _aggregate(inputs, data_root, data_repo, env_cfg, test))
        timings[f"round{rnd}_data_s"] = time.perf_counter() - t
        t = time.perf_counter()
        if rnd == 0 and cfg.round0_checkpoint:
            ckpt = (Path(cfg.round0_checkpoint), checkpoint_key(Path(cfg.round0_checkpoint)))
        else:
            ckpt = _train(cfg, data, test, rdir / "train")
        timings[f"round{rnd}_train_s"] = time.perf_counter() - t
        if cfg.eval_episodes > 0:
            rows.append((f"round {rnd}", evaluate_checkpoint(cfg, ckpt[0], env_cfg, rdir / "eval.json", ckpt[1])))
            write_table(rows, cfg.eval_suites, out)
    _remove_later_rounds(out, cfg.rounds)
    table = write_table(rows, cfg.eval_suites, out) if rows else ""
    final = ckpt[0].resolve()
    summary = {"final_checkpoint": str(final.relative_to(out.resolve())) if final.is_relative_to(out.resolve())
               else str(final), "rollouts": rollout_summaries,
               "timings_s": {k: round(v, 1) for k, v in timings.items()}, "table": table}  # fmt: skip
    write_json_atomic(out / "summary.json", summary)
    # the returned summary names folders as this process sees them (the file: relative to the output folder)
    return {**summary, "output_dir": str(out), "final_checkpoint": str(ckpt[0])}


def _remove_later_rounds(out: Path, rounds: int) -> None:
    """Rounds beyond ``rounds`` left by an earlier run with more rounds would sit beside this run's table."""
    for rdir in out.glob("round_*"):
        if rdir.is_dir() and rdir.name[6:].isdigit() and int(rdir.name[6:]) > rounds:
            remove(rdir)
