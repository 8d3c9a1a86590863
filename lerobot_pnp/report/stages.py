"""The study's stage keys (``lerobot_pnp.cache``): its datasets and evaluations, and what a study wrote.

A dataset is keyed by its generation settings; a training by ``methods.train_stage``; an evaluation by the
trained artefact's key (or the data's), the effective env configs of its suite, its episode count and seeds,
and, for an evaluation whose count the episode rule chooses (``config.EpisodeRule``), the rule's parameters.
"""

from __future__ import annotations

import json
from pathlib import Path

from lerobot_pnp.cache import STAGE_FILE, Stage, code_versions, same_env_configs
from lerobot_pnp.dataset.merge import GENERATION_FILE
from lerobot_pnp.dataset.workdir import remove_generation
from lerobot_pnp.errors import OtherSettingsError
from lerobot_pnp.report import adapters
from lerobot_pnp.report.methods import train_stage

# The files a study writes at the top of its folder: every run rewrites them, so claiming one into the manifest of
# a folder written before manifests loses nothing the study would not overwrite anyway
STUDY_FILES = ("study_config.json", "report.md", "summary.json")
# Its folders, and where each holds the stage records that prove the study wrote it
STUDY_RECORDS = {"train": "*/*/stage.json", "evals": "*/*/*.json", "lerobot_eval_cli": "*/stage.json"}
# The eval batch size of every evaluation recorded before it was a key part (StudyConfig's default then and now)
EVAL_BATCH_SIZE_BEFORE = {"eval_batch_size": 50}


def written_by_the_study(entry: Path) -> bool:
    """Whether a top-level entry of a study folder written before manifests is provably the study's (and may
    be claimed, so that ``--fresh`` deletes it): its files by name; a folder only by what it holds, never by
    its name alone: a dataset by its stage record or by its generator's record naming it as the study names
    its datasets (``adapters.dataset_config``), train, evals and the cross-check by a stage record, the figures
    when the study's ``summary.json`` lists every file in them. A link is never the study's."""
    if entry.is_symlink():
        return False
    if entry.name in STUDY_FILES:
        return entry.is_file()
    if not entry.is_dir():
        return False
    if entry.name == "dataset" or entry.name.startswith("dataset_"):
        made = _json(entry / GENERATION_FILE)
        made = made.get("generation") if isinstance(made, dict) else None
        return _is_record(entry / STAGE_FILE, "dataset") or (
            isinstance(made, dict) and made.get("repo_id") == f"local/{entry.name}"
        )
    if entry.name in STUDY_RECORDS:
        return any(_is_record(p) for p in entry.glob(STUDY_RECORDS[entry.name]))
    if entry.name == "figures":
        summary = _json(entry.parent / "summary.json")
        drawn = summary.get("figures") if isinstance(summary, dict) else None
        files = list(entry.iterdir())
        return isinstance(drawn, list) and bool(files) and all(p.is_file() and p.name in drawn for p in files)
    return False


def _json(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _is_record(path: Path, stage: str | None = None) -> bool:
    """Whether ``path`` is a stage record (``cache.Stage``), of ``stage`` when given."""
    data = _json(path) if not path.is_symlink() else None
    if not isinstance(data, dict) or not isinstance(data.get("key"), str) or not isinstance(data.get("parts"), dict):
        return False
    return stage is None or data["parts"].get("stage") == stage


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
    record of how it was made, and replaced only when that differs (``OtherSettingsError``); any other
    configuration error is the command's, found before anything is deleted. With ``report_only`` it is left as
    it is (the summary says so, and every stage keyed on it is then left out of the report)."""
    root = out / name
    stage = Stage(root / STAGE_FILE, dataset_parts(cfg, changes))
    if stage.done(f"dataset {name}"):
        return {"root": str(root), "status": "reused"}, stage.key
    if cfg.report_only:
        changed = stage.changes()
        status = "missing" if changed is None else f"stale ({', '.join(changed)})"
        return {"root": str(root), "status": f"{status}: not generated (report_only)"}, stage.key
    args = (root, cfg.num_episodes, cfg.dataset_seed, cfg.workers, cfg.task_preset)
    adapters.dataset_config(*args, env_changes=changes)  # a mistyped flag stops here, with the dataset untouched
    stage.invalidate()
    try:
        summary = adapters.generate_dataset(*args, env_changes=changes)
    except OtherSettingsError as err:  # made with other settings: not this study's dataset any more
        print(f"  dataset {name}: regenerated ({err})", flush=True)
        remove_generation(root)
        summary = adapters.generate_dataset(*args, env_changes=changes)
    stage.commit()
    return summary, stage.key


def eval_stage(path: Path, method, ctx, n_episodes: int, env_parts: list, cfg, rule=None) -> Stage:
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
        **({"episodes_rule": rule.key()} if rule is not None else {}),
    }
    return Stage(path, parts, compare={"env_parts": same_env_configs}, dropped=("suite",), added=EVAL_BATCH_SIZE_BEFORE)


def episode_rule(cfg, method, suite, n_demos: int | None):
    """The episode rule an evaluation runs under (``config.EpisodeRule``), or None for the suite's whole n: the
    rule off, a method of its ``fixed_methods``, a data-efficiency run (its curve compares equal counts), or a
    suite of several parts (``Suite.part_episodes`` lays out each part's seeds from n, so a shorter run would
    not be the first episodes of the fixed one: such suites stay at their n). A method of its ``claim_methods``
    runs under its ``ExtendedRule`` (at least n, more where the interval is wide)."""
    rule = cfg.episodes_rule
    if rule is None or n_demos is not None or len(suite.parts) != 1:
        return None
    return rule.for_method(method.name)


def truncated_record(stage: Stage, rule, n_episodes: int, cfg) -> dict | None:
    """A fixed-n record at ``stage``'s path, cut to the rule's stopping block, when that is exactly what a fresh
    run under ``rule`` would produce; else None. Exact when the record's key is ``stage``'s but for the rule
    and its ``n_episodes`` (same artefact, conditions, seeds and batch size), its seeds are the consecutive ones
    from ``eval_seed``, it holds the episodes up to where the rule stops, and its batch is the one a fresh run's
    would be (smaller than the eval batch only when both are n). The record itself stays as it is (valid for a
    fixed evaluation); the cut is made again on every reuse, with its wall time estimated (``share_of_time``)."""
    stored = stage.stored()
    if stored is None or "episodes_rule" in stored["parts"] or not isinstance(stored.get("episodes"), list):
        return None
    n_stored = stored["parts"].get("n_episodes")
    parts = {k: v for k, v in stage.parts.items() if k != "episodes_rule"} | {"n_episodes": n_stored}
    fixed = Stage(stage.record, parts, compare=stage.compare, dropped=stage.dropped, added=stage.added)
    episodes = sorted(stored["episodes"], key=lambda e: e["seed"])
    if fixed.changes() != [] or [e["seed"] for e in episodes] != list(range(cfg.eval_seed, cfg.eval_seed + n_stored)):
        return None
    keep = rule.stop_at([e["success"] for e in episodes], n_episodes, cfg.eval_batch_size)
    if keep is None or min(cfg.eval_batch_size, n_stored) != min(cfg.eval_batch_size, keep):
        return None
    wall_s = stored.get("wall_s", 0.0) * share_of_time(episodes, keep)
    extra = {k: v for k, v in stored.items() if k not in ("key", "parts", "episodes", "wall_s")}
    return {**extra, "wall_s": wall_s, "episodes": episodes[:keep], "truncated_from": n_stored}


def share_of_time(episodes: list[dict], keep: int) -> float:
    """The share of an evaluation's wall time its first ``keep`` episodes took, estimated by their simulated
    steps (a batch costs the sum of its episodes' lengths: ``closed_loop.EpisodeRecorder``)."""
    total = sum(e["steps"] for e in episodes)
    return sum(e["steps"] for e in episodes[:keep]) / total if total else keep / max(1, len(episodes))
