"""Runs that cannot collide or waste work: a training folder is held for its run and ``--overwrite`` replaces
the run there (never a user's file); ``viz --save`` checks its destination before any rollout; an eval
batch size below 1 is refused instead of silently running batches of one."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
import torch

torch.set_num_threads(1)

from keyframe_synth import REPO_ID, make_keyframe_dataset  # noqa: E402

from lerobot_pnp.errors import ConfigError, PnPError, one_line  # noqa: E402
from lerobot_pnp.outputs import OutputFolder  # noqa: E402
from lerobot_pnp.policy import PnpLstmConfig  # noqa: E402
from lerobot_pnp.train_fast import TrainFastConfig, train_fast  # noqa: E402


@pytest.fixture(scope="module")
def dataset_root(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("safety_ds") / "keyframes"
    make_keyframe_dataset(root, n_episodes=12, splits={"train": "0:10", "test": "10:12"})
    return root


def _cfg(dataset_root, out, **kw) -> TrainFastConfig:
    return TrainFastConfig(
        dataset_repo_id=REPO_ID,
        dataset_root=str(dataset_root),
        policy=PnpLstmConfig(device="cpu", hidden_size=8),
        epochs=1,
        batch_size=4,
        output_dir=str(out),
        progress=False,
        **kw,
    )


def _previous_run(out: Path, step: str = "000999") -> None:
    """What an earlier training run left in ``out``: a checkpoint, the ``last`` link and its files."""
    (out / "checkpoints" / step / "pretrained_model").mkdir(parents=True)
    (out / "checkpoints" / step / "pretrained_model" / "config.json").write_text("{}")
    (out / "checkpoints" / "last").symlink_to(step)
    (out / "train_fast_config.json").write_text(json.dumps({"seed": 7, "dataset_repo_id": "x", "policy": {},
                                                            "output_dir": str(out)}))  # fmt: skip
    (out / "loss_curve.csv").write_text("epoch\n0\n")


# ---- one run per training folder ------------------------------------------------------------------


def test_a_second_run_into_a_folder_in_use_fails_at_once_and_writes_nothing(dataset_root, tmp_path):
    out = tmp_path / "run"
    _previous_run(out)
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    first_run = OutputFolder(out, "lerobot-pnp train")  # the first run, still training
    with (
        first_run,
        pytest.raises(PnPError, match="another command is writing .*`lerobot-pnp train` does not wait") as err,
    ):
        train_fast(_cfg(dataset_root, out, overwrite=True))
    assert "\n" not in one_line(err.value)
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before  # the first run's files untouched


def test_overwrite_replaces_the_previous_run(dataset_root, tmp_path):
    out = tmp_path / "run"
    _previous_run(out)
    result = train_fast(_cfg(dataset_root, out, overwrite=True, seed=3))
    steps = sorted(p.name for p in (out / "checkpoints").iterdir())
    assert steps == [f"{result.steps:06d}", "last"]  # no stale checkpoint beside the new one
    assert (out / "checkpoints" / "last").resolve() == result.checkpoint_dir.parent.resolve()
    assert json.loads((out / "train_fast_config.json").read_text())["seed"] == 3
    assert len((out / "loss_curve.csv").read_text().splitlines()) == 3  # header, before training, epoch 1


def test_overwrite_keeps_a_users_file_and_refuses_one_under_a_run_files_name_before_any_work(dataset_root, tmp_path):
    out = tmp_path / "run"
    _previous_run(out)
    (out / "notes.txt").write_text("mine")
    train_fast(_cfg(dataset_root, out, overwrite=True))  # the run is replaced, the user's notes stay
    assert (out / "notes.txt").read_text() == "mine" and not (out / "checkpoints" / "000999").exists()
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "loss_curve.csv").write_text("my own curve")  # a user's file under a name a run writes
    before = sorted(p.relative_to(mine) for p in mine.rglob("*"))
    with pytest.raises(ConfigError, match="loss_curve.csv") as err:
        _cfg(dataset_root, mine, overwrite=True)
    assert "\n" not in one_line(err.value) and "did not write" in str(err.value)
    assert sorted(p.relative_to(mine) for p in mine.rglob("*")) == before
    # a file that appears after the config was checked is caught under the lock, before anything is deleted
    cfg = _cfg(dataset_root, tmp_path / "other", overwrite=True)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "checkpoints").mkdir()
    (tmp_path / "other" / "checkpoints" / "mine.txt").write_text("mine")
    with pytest.raises(ConfigError, match="checkpoints"):
        train_fast(cfg)
    assert (tmp_path / "other" / "checkpoints" / "mine.txt").read_text() == "mine"


def test_a_run_failing_before_it_writes_leaves_no_folder(tmp_path):
    out = tmp_path / "run"
    with pytest.raises(PnPError):
        train_fast(_cfg(tmp_path / "no_dataset", out))
    assert not out.exists()


def test_overwrite_through_the_cli_is_one_line(dataset_root, tmp_path, capsys):
    from lerobot_pnp.cli import main

    out = tmp_path / "run"
    out.mkdir()
    (out / "loss_curve.csv").write_text("x")
    ds = ["--dataset_repo_id", REPO_ID, "--dataset_root", str(dataset_root), "--output_dir", str(out)]
    assert main(["train", *ds, "--overwrite", "true"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "loss_curve.csv" in err, err
    assert (out / "loss_curve.csv").read_text() == "x"


# ---- viz --save: the destination first ------------------------------------------------------------


def _read_only_dir(tmp_path: Path, monkeypatch) -> Path:
    """A folder this process cannot write into: a 0555 folder; for root (whom permission bits do not stop), a
    read-only mount, or where there is none the kernel's answer for one (``os.access`` says no for that folder)."""
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    if os.geteuid() != 0:
        return ro
    for line in Path("/proc/mounts").read_text().splitlines():
        where, options = line.split()[1], line.split()[3]
        if "ro" in options.split(",") and Path(where).is_dir() and not os.access(where, os.W_OK):
            return Path(where)
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: Path(p) != ro and real_access(p, mode, **kw))
    return ro


@pytest.mark.parametrize("where", ["read_only", "folder", "under_a_file"])
def test_viz_save_to_an_unwritable_place_fails_before_any_rollout(tmp_path, monkeypatch, where):
    from lerobot_pnp.viz import VizConfig, sources, visualize

    def loaded(*args, **kwargs):
        raise AssertionError("the dataset was loaded before the destination was checked")

    monkeypatch.setattr(sources, "open_dataset", loaded)
    if where == "read_only":
        dest = _read_only_dir(tmp_path, monkeypatch) / "rec.rrd"
    elif where == "folder":
        dest = tmp_path / "rec.rrd"
        dest.mkdir()
    else:
        (tmp_path / "file").write_text("x")
        dest = tmp_path / "file" / "sub" / "rec.rrd"
    with pytest.raises(ConfigError, match="save") as err:
        visualize(VizConfig(repo_id="t/x", root=str(tmp_path / "ds"), save=str(dest)))
    assert "\n" not in one_line(err.value)


# ---- eval batch size ---------------------------------------------------------------------------


@pytest.mark.parametrize("batch", [0, -3])
def test_an_eval_batch_below_one_is_refused(batch):
    from lerobot_pnp.closed_loop import eval_lerobot_policy
    from lerobot_pnp.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.report.config import StudyConfig

    with pytest.raises(ConfigError, match=f"eval_batch_size must be an integer >= 1.*got {batch}"):
        StudyConfig(preset="quick", eval_batch_size=batch)
    with pytest.raises(ConfigError, match="batch_size must be >= 1"):
        eval_lerobot_policy(None, None, None, BaxterPnPEnvConfig(), 4, 0, batch)


def test_a_training_batch_below_one_names_the_value_in_dagger():
    from lerobot_pnp.dagger import DaggerConfig

    with pytest.raises(ConfigError, match="batch_size must be >= 1 .*got 0"):
        DaggerConfig(batch_size=0)


def test_an_eval_batch_below_one_is_one_line_on_the_command_line(tmp_path, capsys):
    from lerobot_pnp.cli import main

    assert main(["report", "--preset", "quick", "--eval_batch_size", "0", "--output_dir", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "eval_batch_size must be an integer >= 1" in err, err
    assert not (tmp_path / "s").exists()
