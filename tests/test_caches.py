"""Cached stages that cannot lie: DAgger and the study keyed by what produced them, one lock per
output folder, ``--fresh`` that deletes only the study's files, relative paths, pool workers that die with
the study, checkpoints that carry their task, and the smaller robustness cases. One test per case."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import zygote

from lerobot_pnp import cli
from lerobot_pnp.cache import Stage
from lerobot_pnp.errors import ConfigError, DatasetError, ResetOptionError
from lerobot_pnp.outputs import OutputFolder

DAGGER = {
    "num_episodes": 6,
    "rounds": 1,
    "rollouts_per_round": 2,
    "rollout_suites": ["quiet_drop"],
    "eval_suites": ["quiet"],
    "n_episodes": 2,
    "epochs": 2,
    "progress": False,
}


def _argv(cfg: dict) -> list[str]:
    """``--name value`` flags of a config dict (lists as draccus reads them)."""
    out = []
    for k, v in cfg.items():
        if isinstance(v, list):
            v = "[" + ",".join(str(x) if not isinstance(x, dict) else json.dumps(x) for x in v) + "]"
        out += [f"--{k}", str(v).lower() if isinstance(v, bool) else str(v)]
    return out


def _dagger(out: Path, capsys=None, **changes) -> int:
    return cli.main(["dagger", "--output_dir", str(out), *_argv({**DAGGER, **changes})])


def _mtimes(root: Path, pattern: str = "*") -> dict[Path, int]:
    return {p: p.stat().st_mtime_ns for p in root.rglob(pattern) if p.is_file()}


CKPT = Path("round_01/train/checkpoints/last/pretrained_model")


@pytest.fixture(scope="module")
def dagger_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("dagger") / "base"
    assert _dagger(out) == 0
    return out


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst, symlinks=True)
    return dst


# --------------------------------------------------------------------------------------------------- case 1
@pytest.mark.slow
def test_1_a_second_dagger_on_the_same_folder_is_refused_and_a_stage_without_record_is_redone(
    dagger_run, tmp_path, capsys
):
    out = _copy(dagger_run, tmp_path / "dg")
    with OutputFolder(out, "lerobot-pnp dagger"):  # as a running `lerobot-pnp dagger` holds it
        before = _mtimes(out)
        assert _dagger(out) == 2
    err = capsys.readouterr().err.strip()
    assert "`lerobot-pnp dagger` does not wait" in err and len(err.splitlines()) == 1, err
    assert _mtimes(out) == before  # nothing read or written
    # a demos folder that was never recorded as finished (a truncated parquet, as a concurrent writer left it)
    parquet = next((out / "demos" / "data").rglob("*.parquet"))
    parquet.write_bytes(parquet.read_bytes()[:100])
    (out / "demos" / "stage.json").unlink()
    assert _dagger(out) == 0
    import pyarrow.parquet as pq

    info = json.loads((out / "demos/meta/info.json").read_text())
    assert pq.read_table(next((out / "demos" / "data").rglob("*.parquet"))).num_rows == info["total_frames"]
    assert info["total_episodes"] == 6


# --------------------------------------------------------------------------------------------------- case 2
@pytest.mark.slow
def test_2_dagger_reruns_the_stages_whose_config_changed(dagger_run, tmp_path, capsys):
    out = _copy(dagger_run, tmp_path / "dg")
    ckpt0 = out / "round_00/train/checkpoints/last/pretrained_model/model.safetensors"
    evals = out / "round_00/eval.json"
    stamp = {p: p.stat().st_mtime_ns for p in (ckpt0, evals, out / CKPT / "model.safetensors")}
    assert _dagger(out, eval_seed=123) == 0  # only the evaluations depend on it
    assert ckpt0.stat().st_mtime_ns == stamp[ckpt0] and evals.stat().st_mtime_ns != stamp[evals]
    assert "eval_seed" in capsys.readouterr().out  # the re-run names what changed
    assert _dagger(out, seed=1) == 0
    assert json.loads((out / "demos/stage.json").read_text())["parts"]["seed"] == 1
    assert ckpt0.stat().st_mtime_ns != stamp[ckpt0]
    assert _dagger(out, seed=1, num_episodes=8) == 0
    info = json.loads((out / "round_01/data/meta/info.json").read_text())
    assert info["total_episodes"] == 8 + 2 and info["splits"]["test"] == "7:8"  # the test range of these demos
    other = _copy(out / "round_00/train/checkpoints/last/pretrained_model", tmp_path / "round0")
    rollouts = out / "round_01/rollouts.json"
    trained = json.loads(rollouts.read_text())["key"]
    assert _dagger(out, seed=1, num_episodes=8, round0_checkpoint=str(other)) == 0
    before = json.loads(rollouts.read_text())["key"]
    assert before != trained  # rolled out again: a checkpoint passed in is keyed by its content
    assert _dagger(out, seed=1, num_episodes=8, round0_checkpoint=str(other)) == 0
    assert json.loads(rollouts.read_text())["key"] == before  # the same checkpoint content: the same key
    (other / "model.safetensors").write_bytes((out / CKPT / "model.safetensors").read_bytes())
    assert _dagger(out, seed=1, num_episodes=8, round0_checkpoint=str(other)) == 0
    assert json.loads(rollouts.read_text())["key"] != before  # another round-0 policy: rolled out again


# --------------------------------------------------------------------------------------------------- case 5
def test_5_a_moved_dagger_folder_keeps_working_and_never_reads_its_old_place(dagger_run, tmp_path):
    old = _copy(dagger_run, tmp_path / "old")
    done = json.loads((old / "round_01/train/done.json").read_text())
    assert not Path(done["checkpoint"]).is_absolute()
    assert not Path(json.loads((old / "summary.json").read_text())["final_checkpoint"]).is_absolute()
    new = tmp_path / "new"
    old.rename(new)
    stamps = _mtimes(new, "*.safetensors")
    (old / CKPT).mkdir(parents=True)  # whatever now sits at the old place is not a checkpoint of this run
    (old / CKPT / "config.json").write_text("{broken")
    from lerobot_pnp.dagger import DaggerConfig, run_dagger

    summary = run_dagger(DaggerConfig(output_dir=str(new), **DAGGER))
    assert Path(summary["final_checkpoint"]).resolve() == (new / CKPT).resolve()
    assert _mtimes(new, "*.safetensors") == stamps  # nothing re-run


# --------------------------------------------------------------------------------------------------- study
STUDY = {
    "preset": "quick",
    "num_episodes": 10,
    "workers": 1,
    "epochs": 1,
    "train_seeds": [1000],
    "methods": ["lookup_table", "clocked_lstm"],
    "cli_check_episodes": 0,
}
SUITES = "[{name: nominal, n_episodes: 2}]"


def _study(out: Path, suites: str = SUITES, **changes) -> int:
    return cli.main(["report", "--output_dir", str(out), *_argv({**STUDY, **changes}), "--suites", suites])


@pytest.fixture(scope="module")
def study_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("study") / "s"
    assert _study(out) == 0
    return out


def _evaluated_seeds(out: Path, method: str, tag: str) -> list[int]:
    return [e["seed"] for e in json.loads((out / f"evals/{method}/seed{tag}/nominal.json").read_text())["episodes"]]


@pytest.mark.slow
def test_3_the_study_reruns_what_a_changed_flag_determines_and_reports_that_config(study_run, tmp_path):
    out = _copy(study_run, tmp_path / "s")
    model = out / "train/clocked_lstm/seed1000/checkpoints/last/pretrained_model/model.safetensors"
    trained = model.stat().st_mtime_ns
    assert _study(out, eval_seed=200_000) == 0
    assert model.stat().st_mtime_ns == trained  # the training does not depend on the evaluation seeds
    assert _evaluated_seeds(out, "clocked_lstm", "1000") == [200_000, 200_001]
    assert _evaluated_seeds(out, "lookup_table", "-") == [200_000, 200_001]
    assert json.loads((out / "summary.json").read_text())["config"]["eval_seed"] == 200_000
    assert "200000 onwards" in (out / "report.md").read_text()
    assert _study(out, eval_seed=200_000, epochs=2) == 0
    assert model.stat().st_mtime_ns != trained
    assert json.loads((out / "train/clocked_lstm/seed1000/stage.json").read_text())["parts"]["epochs"] == 2
    suites3 = "[{name: nominal, n_episodes: 3}]"
    assert _study(out, suites=suites3, eval_seed=200_000, epochs=2, num_episodes=12, dataset_seed=7) == 0
    info = json.loads((out / "dataset/meta/info.json").read_text())
    assert info["total_episodes"] == 12
    assert json.loads((out / "dataset/meta/pnp_generate.json").read_text())["generation"]["seed"] == 7
    assert _evaluated_seeds(out, "clocked_lstm", "1000") == [200_000, 200_001, 200_002]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["config"]["num_episodes"] == 12 and summary["config"]["dataset_seed"] == 7
    assert summary["success"]["nominal"]["clocked_lstm"]["n"] == 3
    train_stage = json.loads((out / "train/clocked_lstm/seed1000/stage.json").read_text())
    assert train_stage["parts"]["data"] == json.loads((out / "dataset/stage.json").read_text())["key"]


# --------------------------------------------------------------------------------------------------- case 4
def test_4_fresh_deletes_only_what_the_study_wrote_and_keeps_the_users_files(tmp_path, monkeypatch):
    from lerobot_pnp.outputs import OutputFolder
    from lerobot_pnp.report import run
    from lerobot_pnp.report.folder import COMMAND

    def stop(*args, **kwargs):
        raise RuntimeError("stopped before any stage")

    monkeypatch.setattr(run, "_prepare", stop)
    out = tmp_path / "s"
    (out / "thesis").mkdir(parents=True)
    (out / "thesis" / "chapter1.tex").write_text("mine")
    with OutputFolder(out, COMMAND) as folder:  # what an earlier study wrote there
        folder.claim("dataset")
        (out / "dataset" / "meta").mkdir(parents=True)
        folder.write_text("report.md", "old")
    with pytest.raises(RuntimeError, match="stopped before any stage"):
        _study_cfg(out, fresh=True)
    assert (out / "thesis" / "chapter1.tex").read_text() == "mine"
    assert sorted(p.name for p in out.iterdir()) == [".pnp_manifest.json", "thesis"]
    # a study folder written before manifests: its own entries are known, a user's file stays
    study = tmp_path / "t"
    (study / "evals" / "m" / "seed1").mkdir(parents=True)
    (study / "evals" / "m" / "seed1" / "nominal.json").write_text(json.dumps({"key": "k", "parts": {}}))
    (study / "study_config.json").write_text("{}")
    (study / "notes.txt").write_text("mine")
    with pytest.raises(RuntimeError, match="stopped before any stage"):
        _study_cfg(study, fresh=True)
    assert sorted(p.name for p in study.iterdir()) == [".pnp_manifest.json", "notes.txt"]
    assert (study / "notes.txt").read_text() == "mine"


def _study_cfg(out: Path, **changes):
    from lerobot_pnp.report.run import StudyConfig, run_study

    return run_study(StudyConfig(output_dir=str(out), **{**STUDY, **changes}))


# --------------------------------------------------------------------------------------------------- case 6
def _sleeping_job(job, log_dir):
    """A stand-in for run_job: records its pid and works for a long time."""
    Path(log_dir, f"{os.getpid()}").write_text("")
    time.sleep(120)


_ORPHANS = """
import sys, time
sys.path.insert(0, {tests!r})
from test_caches import _sleeping_job
from lerobot_pnp.report.schedule import Job, run_jobs
if __name__ == "__main__":
    list(run_jobs([Job("clocked_lstm", "1", None), Job("lookup_table", "-", None)], ({log!r},), 2, fn=_sleeping_job))
"""


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.slow
def test_6_pool_workers_die_with_the_study(tmp_path):
    log = tmp_path / "pids"
    log.mkdir()
    script = tmp_path / "study.py"
    script.write_text(_ORPHANS.format(tests=str(Path(__file__).parent), log=str(log)))
    main = subprocess.Popen([sys.executable, str(script)], env={**os.environ, "PYTHONPATH": os.getcwd()})
    deadline = time.time() + 600  # the pool's fork server imports torch and LeRobot first: slow on a loaded machine
    while len(list(log.iterdir())) < 2 and time.time() < deadline and main.poll() is None:
        time.sleep(0.2)
    workers = [int(p.name) for p in log.iterdir()]
    assert len(workers) == 2 and all(_alive(w) for w in workers)
    main.send_signal(signal.SIGKILL)
    main.wait()
    deadline = time.time() + 20
    while any(_alive(w) for w in workers) and time.time() < deadline:
        time.sleep(0.2)
    assert not any(_alive(w) for w in workers)


# --------------------------------------------------------------------------------------------------- case 7
def test_7_a_checkpoint_saved_by_lerobot_carries_its_task_and_a_bad_record_is_refused(dagger_run, tmp_path):
    from lerobot.common.train_utils import save_checkpoint
    from lerobot.configs.default import DatasetConfig
    from lerobot.configs.train import TrainPipelineConfig
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata
    from lerobot.policies.factory import make_policy

    from lerobot_pnp.integration.recorded_task import copy_recorded, read_recorded
    from lerobot_pnp.policy import PnpLstmConfig

    root = _copy(dagger_run / "demos", tmp_path / "demos")
    task = read_recorded(root)
    # lerobot-train's own save (policy, config and processors): the plugin's policy writes the task too
    policy = make_policy(
        PnpLstmConfig(mode="recovering", hidden_size=8), ds_meta=LeRobotDatasetMetadata("x", root=root)
    )
    cfg = TrainPipelineConfig(dataset=DatasetConfig(repo_id="x", root=str(root)), policy=policy.config)
    optimizer = __import__("torch").optim.SGD(policy.parameters(), lr=0.1)
    save_checkpoint(tmp_path / "ckpt", 1, cfg, policy, optimizer)
    pretrained = tmp_path / "ckpt" / "pretrained_model"
    assert json.loads((pretrained / "baxter_pnp_env.json").read_text()) == task
    changed = {**task, "place_low": [0.6, -0.1], "place_high": [0.6, -0.1]}
    (root / "meta/baxter_pnp_env.json").write_text(json.dumps(changed))  # the root regenerated, another target
    assert read_recorded(pretrained) == task
    # the fast trainer's checkpoints (`lerobot-pnp train`) carry it the same way
    assert read_recorded(dagger_run / "round_00/train/checkpoints/last/pretrained_model") == read_recorded(
        dagger_run / "demos"
    )
    for bad, what in (
        ('{"type": "baxter_pnp", "nudge_max": NaN}', "non-finite"),
        ('{"type": "baxter_pnp", "object_low": [0.7, 0.1], "object_high": [0.5]}', "invalid"),
        ("{corrupt", "cannot read"),
    ):
        (root / "meta/baxter_pnp_env.json").write_text(bad)
        with pytest.raises(ConfigError, match=what):
            copy_recorded(root, tmp_path)
        with pytest.raises(ConfigError, match=what):
            read_recorded(root)
    assert not (tmp_path / "baxter_pnp_env.json").exists()
    rc = cli.main(["train", "--dataset_repo_id", "x", "--dataset_root", str(root), "--epochs", "1",
                   "--output_dir", str(tmp_path / "train"), "--progress", "false"])  # fmt: skip
    assert rc == 2 and not list((tmp_path / "train").rglob("baxter_pnp_env.json"))


# --------------------------------------------------------------------------------------------------- case 8
def test_8_merged_stats_index_ranges(tmp_path):
    from lerobot.datasets.io_utils import load_stats

    from lerobot_pnp.dataset import GenerateConfig, generate

    summary = generate(GenerateConfig(repo_id="t/m", root=str(tmp_path / "m"), num_episodes=4, tasks=2, workers=1,
                                      progress=False))  # fmt: skip
    assert summary["shards"] == 2
    stats = load_stats(tmp_path / "m")
    assert float(stats["episode_index"]["max"][0]) == 3 and float(stats["episode_index"]["min"][0]) == 0
    assert float(stats["index"]["max"][0]) == summary["frames"] - 1


def test_8_a_failed_slurm_submission_does_not_block_a_local_run(tmp_path, monkeypatch):
    from lerobot_pnp.dataset import GenerateConfig, generate

    monkeypatch.setenv("PATH", str(tmp_path))  # no sbatch here
    root = tmp_path / "d"
    with pytest.raises(DatasetError, match="sbatch"):
        generate(GenerateConfig(repo_id="t/s", root=str(root), num_episodes=2, executor="slurm", progress=False))
    assert not (root / ".pnp_work").exists()
    monkeypatch.undo()
    assert generate(GenerateConfig(repo_id="t/s", root=str(root), num_episodes=2, workers=1, progress=False))


def test_8_nan_and_zero_std_in_a_checkpoint_are_named_as_the_checkpoints(dagger_run, tmp_path, caplog):
    from safetensors.numpy import load_file, save_file

    from lerobot_pnp.evaluation.checkpoints import IncompatiblePolicyError, PolicyLoadError, load_policy
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    ckpt = _copy(dagger_run / CKPT, tmp_path / "ckpt")
    weights = load_file(ckpt / "model.safetensors")
    name = next(iter(weights))
    save_file({**weights, name: np.full_like(weights[name], np.nan)}, ckpt / "model.safetensors")
    with pytest.raises(PolicyLoadError, match=f"corrupt: its weights .*{name}.* contain NaN"):
        load_policy(ckpt)
    with pytest.raises(PolicyLoadError, match=f"corrupt: its weights .*{name}.* contain NaN"):  # the study's path too
        load_policy(ckpt, env_cfg=BaxterPnPEnvConfig(preset="full"))
    (ckpt / "model.safetensors").write_bytes((dagger_run / CKPT / "model.safetensors").read_bytes())
    stats_file = next(ckpt.glob("policy_preprocessor_step_*normalizer*.safetensors"))
    stats = load_file(stats_file)
    std = next(k for k in stats if k.endswith(".std"))
    save_file({**stats, std: np.zeros_like(stats[std])}, stats_file)
    with caplog.at_level("WARNING"):
        load_policy(ckpt)
    assert caplog.text.count("std 0") == 1
    with caplog.at_level("WARNING"):
        load_policy(ckpt)  # a study loads a checkpoint once per suite: flagged once, not once per load
    assert caplog.text.count("std 0") == 1
    # with an env config, the environment_state must be that env's exactly (the dagger run's task is `full`)
    assert load_policy(ckpt, env_cfg=BaxterPnPEnvConfig(preset="full")).policy.config.type == "pnp_lstm"
    with pytest.raises(IncompatiblePolicyError, match=r"environment_state' has shape \(7,\), this env gives \(3,\)"):
        load_policy(ckpt, env_cfg=BaxterPnPEnvConfig(preset="paper"))
    mean = next(k for k in stats if k.endswith(".mean"))
    save_file({**stats, mean: np.full_like(stats[mean], np.inf)}, stats_file)
    with pytest.raises(PolicyLoadError, match="normalisation stats .* contain NaN/inf"):
        load_policy(ckpt)


def test_8_bad_actions_episode_length_and_reset_height_are_clear_errors(keyframe_env):
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    keyframe_env.reset(seed=0)
    for action in ("abc", np.full(8, 1 + 2j), [[0.0] * 8, [0.0]]):
        with pytest.raises(ConfigError, match="real numbers"):
            keyframe_env.step(action)
    with pytest.raises(ConfigError, match="episode_length"):
        BaxterPnPEnvConfig(episode_length=10**7)
    with pytest.raises(ConfigError, match="keyframe_budget"):
        BaxterPnPEnvConfig(control_mode="dense", keyframe_budget=10**6)
    with pytest.raises(ResetOptionError, match="rest height"):
        keyframe_env.reset(seed=0, options={"object_pos": [0.5, 0.3, 0.4]})
    keyframe_env.reset(seed=0, options={"object_pos": [0.5, 0.3, 0.0]})  # z = 0: on the table, as before


def test_stage_records_name_the_changed_parts(tmp_path):
    stage = Stage(tmp_path / "s.json", {"seed": 0, "n": 3})
    assert not stage.done() and stage.changes() is None
    stage.commit(extra=1)
    assert Stage(tmp_path / "s.json", {"seed": 0, "n": 3}).done()
    assert Stage(tmp_path / "s.json", {"seed": 1, "n": 3}).changes() == ["seed"]
    with pytest.raises(ConfigError, match="not finite"):
        Stage(tmp_path / "s.json", {"x": float("nan")})
    (tmp_path / "s.json").write_text("{trunc")
    assert not Stage(tmp_path / "s.json", {"seed": 0, "n": 3}).done()


@pytest.mark.slow
def test_7_stock_lerobot_train_checkpoints_carry_their_task(dagger_run, tmp_path):
    from lerobot_pnp.integration.recorded_task import read_recorded

    root = _copy(dagger_run / "demos", tmp_path / "demos")
    task = read_recorded(root)
    train = Path(sys.executable).with_name("lerobot-train")
    args = ["--policy.type=pnp_lstm", "--policy.mode=recovering", "--policy.max_episode_length=41",
            "--policy.push_to_hub=false", "--policy.device=cpu", "--dataset.repo_id=local/x", f"--dataset.root={root}",
            "--dataset.video_backend=pyav", "--steps=2", "--batch_size=2", "--num_workers=0", "--save_freq=2",
            "--wandb.enable=false", f"--output_dir={tmp_path / 'run'}"]  # fmt: skip
    proc = zygote.run([str(train), *args])  # its entry point, in a process forked from a warm interpreter
    assert proc.returncode == 0, proc.stderr[-2000:]
    pretrained = tmp_path / "run/checkpoints/last/pretrained_model"
    assert json.loads((pretrained / "baxter_pnp_env.json").read_text()) == task
    changed = {**task, "place_low": [0.6, -0.1], "place_high": [0.6, -0.1]}
    (root / "meta/baxter_pnp_env.json").write_text(json.dumps(changed))  # the root regenerated, another target
    assert read_recorded(pretrained) == task


def test_a_task_field_added_since_a_stage_ran_counts_as_unchanged_at_its_paper_value():
    from lerobot_pnp.cache import same_env_configs
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    now = BaxterPnPEnvConfig(preset="full").to_dict()
    old = {k: v for k, v in now.items() if k != "observe_phase"}  # recorded before the field existed
    assert same_env_configs(old, now) and same_env_configs([old], [now])
    assert not same_env_configs(old, {**now, "observe_phase": True})
    assert not same_env_configs({**old, "drop_prob": 0.5}, now)


def test_an_evaluation_is_keyed_by_its_batch_size_and_older_records_count_as_the_default(tmp_path):
    """A learned policy's episode can end differently at another eval batch size (float sums in the network),
    so a record made at one batch size is not reused at another; a record made before the batch size was a
    key part was made at the default (50) and stays valid at 50."""
    from lerobot_pnp.cache import Stage
    from lerobot_pnp.report.stages import EVAL_BATCH_SIZE_BEFORE

    parts = {"stage": "eval", "n_episodes": 10, "eval_seed": 100000}
    old = Stage(tmp_path / "stage.json", parts)  # how the record was written before the part existed
    old.commit()
    at = {b: Stage(tmp_path / "stage.json", {**parts, "eval_batch_size": b}, added=EVAL_BATCH_SIZE_BEFORE)
          for b in (50, 10)}  # fmt: skip
    assert at[50].done() and at[50].changes() == []
    assert not at[10].done() and at[10].changes() == ["eval_batch_size"]
    at[10].commit()  # re-run at 10: now 50 is the one that differs
    assert at[10].done() and at[50].changes() == ["eval_batch_size"]
