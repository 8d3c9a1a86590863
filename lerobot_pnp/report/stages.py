"""The study's stage keys (``lerobot_pnp.cache``): its datasets and evaluations, and what a study wrote.

A dataset is keyed by its generation settings; a training by ``methods.train_stage``; an evaluation by the
trained artefact's key (or the data's), the effective env configs of its suite, its episode count and seeds.
"""

from __future__ import annotations

from pathlib import Path

from lerobot_pnp.cache import STAGE_FILE, Stage, code_versions, same_env_configs
from lerobot_pnp.dataset.workdir import remove_generation
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.report import adapters
from lerobot_pnp.report.methods import train_stage

# What a study wrote before it kept a manifest (its folder holds study_config.json)
STUDY_ENTRIES = (
    "study_config.json",
    "dataset",
    "train",
    "evals",
    "lerobot_eval_cli",
    "report.md",
    "summary.json",
    "figures",
)
# The eval batch size of every evaluation recorded before it was a key part (StudyConfig's default then and now)
EVAL_BATCH_SIZE_BEFORE = {"eval_batch_size": 50}


def written_by_the_study(name: str) -> bool:
    return name in STUDY_ENTRIES or name.removesuffix(".tmp") in STUDY_ENTRIES or name.startswith("dataset_")


def dataset_parts(cfg, changes: dict | None = None) -> dict:
    """What determines a recording: episodes, seed, env changes, code versions, and the task preset when it
    is not the paper's (so the key of a paper study's dataset, and of all it keys, is what it was before)."""
    parts = {
        "stage": "dataset",
        "num_episodes": cfg.num_episodes,
        "seed": cfg.dataset_seed,
        "changes": changes or {},
        "versions": code_versions(),
    }
    if cfg.task_preset != "paper":
        parts["task_preset"] = cfg.task_preset
    return parts


def dataset_stage(out: Path, name: str, cfg, changes: dict | None = None) -> tuple[dict, str]:
    """Generate (or finish, or reuse) the recording ``name``, keyed by what determines it; (summary, key).

    A dataset of other settings (or one without a record) is verified by the generator against its own
    record of how it was made, and replaced when that differs; with ``report_only`` it is left as it is (the
    summary says so, and every stage keyed on it is then left out of the report)."""
    root = out / name
    stage = Stage(root / STAGE_FILE, dataset_parts(cfg, changes))
    if stage.done(f"dataset {name}"):
        return {"root": str(root), "status": "reused"}, stage.key
    if cfg.report_only:
        changed = stage.changes()
        status = "missing" if changed is None else f"stale ({', '.join(changed)})"
        return {"root": str(root), "status": f"{status}: not generated (report_only)"}, stage.key
    stage.invalidate()
    args = (root, cfg.num_episodes, cfg.dataset_seed, cfg.workers, cfg.task_preset)
    try:
        summary = adapters.generate_dataset(*args, env_changes=changes)
    except ConfigError as err:  # made with other settings: not this study's dataset any more
        print(f"  dataset {name}: regenerated ({err})", flush=True)
        remove_generation(root)
        summary = adapters.generate_dataset(*args, env_changes=changes)
    stage.commit()
    return summary, stage.key


def eval_stage(path: Path, method, ctx, n_episodes: int, env_parts: list, cfg) -> Stage:
    """An evaluation's key: the trained artefact's (or the data's), the effective env config of each part of
    its suite (the suite's changes built on the task, as the method runs them), its episodes and seeds; not
    the suite's name, so suites of the same conditions are one evaluation (``coverage.suite_aliases``). The
    name was once a part (``dropped``: an evaluation made then stays valid). A task field added since it ran
    counts as unchanged when its value is the paper's (off). The eval batch size is a part because a learned
    policy's outcome on an episode can depend on it: the network's float sums differ in the last bits with the
    batch, and a marginal grasp amplifies that (records made before it was a part used the default, 50)."""
    parts = {
        "stage": "eval",
        "train": train_stage(method, ctx).key if method.learned else None,
        "data": ctx.data_keys.get(method.data),
        "env_parts": env_parts,
        "n_episodes": n_episodes,
        "eval_seed": cfg.eval_seed,
        "eval_batch_size": cfg.eval_batch_size,
        "versions": code_versions(),
    }
    return Stage(path, parts, compare={"env_parts": same_env_configs}, dropped=("suite",), added=EVAL_BATCH_SIZE_BEFORE)
