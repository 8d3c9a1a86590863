"""Training ``pnp_lstm``: the fast path (lerobot_pnp/train_fast), stock ``lerobot-train``'s windows, and the
``lerobot-pnp train`` command line with bad input (one clear line, exit code, no traceback)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch
import zygote

torch.set_num_threads(1)

from keyframe_synth import (  # noqa: E402
    ACTION,
    N_EPISODES,
    N_TRAIN,
    OBS_ENV,
    OBS_STATE,
    REPO_ID,
    STATE_NAMES,
    T,
    make_keyframe_dataset,
)
from lerobot.datasets import LeRobotDataset  # noqa: E402
from lerobot.policies.factory import make_pre_post_processors  # noqa: E402

from lerobot_pnp.errors import ConfigError, DatasetError  # noqa: E402
from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy  # noqa: E402
from lerobot_pnp.train_fast import (  # noqa: E402
    TrainFastConfig,
    load_keyframe_data,
    normalize_episode_range,
    train_fast,
)

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def dataset_root(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("pnp_ds") / "keyframes"
    make_keyframe_dataset(root, splits={"train": f"0:{N_TRAIN}", "test": f"{N_TRAIN}:{N_EPISODES}"})
    return root


@pytest.fixture(scope="module")
def trained(dataset_root, tmp_path_factory):
    out = tmp_path_factory.mktemp("pnp_train") / "run"
    cfg = TrainFastConfig(
        dataset_repo_id=REPO_ID,
        dataset_root=str(dataset_root),
        policy=PnpLstmConfig(device="cpu", hidden_size=32),
        epochs=80,
        batch_size=8,
        seed=0,
        output_dir=str(out),
        progress=False,
    )
    return train_fast(cfg), out


def _cfg(dataset_root, out, **kw) -> TrainFastConfig:
    return TrainFastConfig(
        dataset_repo_id=REPO_ID, dataset_root=str(dataset_root), output_dir=str(out), progress=False, **kw
    )


# ---- the fast path ------------------------------------------------------------------------------


def test_train_fast_reduces_loss_and_writes_outputs(trained):
    result, out = trained
    h0 = result.history[0]
    assert result.final_train_mse < 0.05 * h0["train_mse"], (h0, result.final_train_mse)
    assert result.final_test_mse < 0.2 * h0["test_mse"], (h0, result.final_test_mse)
    pm = out / "checkpoints" / "last" / "pretrained_model"
    assert (out / "checkpoints" / "last").is_symlink()
    for name in ("config.json", "model.safetensors", "train_config.json", "policy_preprocessor.json"):
        assert (pm / name).is_file(), name
    assert list(pm.glob("policy_preprocessor_step_*_normalizer_processor.safetensors"))
    config = json.loads((pm / "config.json").read_text())
    assert config["type"] == "pnp_lstm" and config["dataset_fps"] == 1  # recorded from the dataset
    assert (out / "loss_curve.png").stat().st_size > 1000
    lines = (out / "loss_curve.csv").read_text().strip().splitlines()
    assert lines[0].startswith("epoch,step,train_mse,test_mse") and len(lines) == 1 + 1 + 80
    err = json.loads((out / "test_keyframe_error.json").read_text())
    assert err["n_episodes"] == N_EPISODES - N_TRAIN and err["n_train_episodes"] == N_TRAIN
    assert "info.json" in err["split"]
    assert list(err["per_joint_mae_deg"]) == STATE_NAMES[:7]
    assert all(math.isfinite(v) for v in err["per_joint_mae_deg"].values())
    assert err["mean_joint_mae_deg"] < 5.0
    assert (out / "train_fast_config.json").is_file()


def test_heldout_cadence_changes_the_curve_not_the_weights(dataset_root, tmp_path):
    """The held-out loss every k epochs (the data-efficiency runs' cadence) is read-only: the same seed trains
    the same weights and ends at the same losses, with fewer points on the curve (the last epoch always)."""
    from safetensors.torch import load_file

    from lerobot_pnp.report.adapters import heldout_every_epochs

    runs = {}
    for every in (1, 4):
        out = tmp_path / f"every{every}"
        kw = dict(policy=PnpLstmConfig(device="cpu", hidden_size=16), epochs=10, batch_size=8, seed=3)
        runs[every] = (train_fast(_cfg(dataset_root, out, eval_every_epochs=every, **kw)), out)
    (dense, out1), (sparse, out4) = runs[1], runs[4]
    weights = [load_file(o / "checkpoints" / "last" / "pretrained_model" / "model.safetensors") for o in (out1, out4)]
    assert weights[0].keys() == weights[1].keys()
    assert all(torch.equal(weights[0][k], weights[1][k]) for k in weights[0])
    assert sparse.final_test_mse == dense.final_test_mse and sparse.final_train_mse == dense.final_train_mse
    assert [h["epoch"] for h in sparse.history] == [0, 4, 8, 10] and len(dense.history) == 11
    # one held-out loss per epoch of the whole split: 10 demos in batches of 64 make one step per epoch
    assert heldout_every_epochs(10, 1120) == 18 and heldout_every_epochs(300, 1120) == 4
    assert heldout_every_epochs(1120, 1120) == 1


def test_init_from_continues_the_weights_and_their_normalisation(trained, dataset_root, tmp_path):
    """A warm start (``init_from``, DAgger's ``warm_start_epochs``) begins where the checkpoint ended: its
    first loss is the checkpoint's final one on the same data (its weights and its statistics, not the
    dataset's), a fresh run begins far above it; a checkpoint of another architecture is one ConfigError."""
    result, out = trained
    ckpt = out / "checkpoints" / "last" / "pretrained_model"
    kw = dict(policy=PnpLstmConfig(device="cpu", hidden_size=32), epochs=2, batch_size=8, seed=5)
    warm = train_fast(_cfg(dataset_root, tmp_path / "warm", init_from=str(ckpt), **kw))
    cold = train_fast(_cfg(dataset_root, tmp_path / "cold", **kw))
    assert warm.history[0]["train_mse"] == pytest.approx(result.final_train_mse, rel=1e-5)
    assert cold.history[0]["train_mse"] > 10 * warm.history[0]["train_mse"]
    with pytest.raises(ConfigError, match="init_from .* do not fit"):
        small = dict(kw, policy=PnpLstmConfig(device="cpu", hidden_size=16))
        train_fast(_cfg(dataset_root, tmp_path / "other", init_from=str(ckpt), **small))
    with pytest.raises(ConfigError, match="not a policy checkpoint"):
        _cfg(dataset_root, tmp_path / "none", init_from=str(tmp_path), **kw)


def test_progress_into_a_log_is_a_few_lines(dataset_root, tmp_path, capsys):
    """Into a pipe or a log (no terminal) the epoch bar is redrawn every 15 s at most (progress.py), not once per
    epoch: a short run writes its first and last state only. On a terminal it is redrawn twice a second."""
    import io

    from lerobot_pnp.support.progress import LOG_INTERVAL_S, redraw_interval_s

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    assert redraw_interval_s(Terminal()) == 0.5 and redraw_interval_s(io.StringIO()) == LOG_INTERVAL_S
    cfg = _cfg(dataset_root, tmp_path / "o", policy=PnpLstmConfig(device="cpu", hidden_size=8), epochs=40)
    cfg.progress = True
    train_fast(cfg)
    err = capsys.readouterr().err
    draws = err.count("pnp_lstm (fast)")
    assert "40/40" in err and 1 <= draws <= 3, err


def test_save_load_roundtrip_identical_actions(trained, dataset_root):
    result, _ = trained
    path = result.checkpoint_dir
    _, episodes = load_keyframe_data(REPO_ID, dataset_root)
    a, b = PnpLstmPolicy.from_pretrained(path), PnpLstmPolicy.from_pretrained(path)
    cfg = PnpLstmConfig.from_pretrained(path)
    cfg.pretrained_path = path  # lerobot#4647: processors need the path to get their stats
    pre, post = make_pre_post_processors(cfg, pretrained_path=str(path))
    raw = episodes.batch(torch.arange(N_TRAIN, N_EPISODES))
    acts = []
    for pol in (a, b):
        pol.reset()
        seq = []
        for k in range(T):
            obs = pre({OBS_STATE: raw[OBS_STATE][:, k], OBS_ENV: raw[OBS_ENV][:, k]})
            with torch.inference_mode():
                seq.append(post(pol.select_action(obs)))
        acts.append(torch.stack(seq, 1))
    assert torch.equal(acts[0], acts[1])
    err = (acts[0][..., :7] - raw[ACTION][..., :7]).abs().mean() * 180 / math.pi
    assert float(err) < 5.0


def test_train_fast_config_from_lerobot_train_json():
    cfg = TrainFastConfig.from_train_config(REPO_ROOT / "configs" / "train_pnp_lstm.json", epochs=3)
    raw = json.loads((REPO_ROOT / "configs" / "train_pnp_lstm.json").read_text())
    assert cfg.dataset_repo_id == raw["dataset"]["repo_id"] and cfg.batch_size == raw["batch_size"]
    assert isinstance(cfg.policy, PnpLstmConfig) and cfg.epochs == 3
    for key, value in raw["policy"].items():
        if key != "type":
            assert getattr(cfg.policy, key) == value, key


def test_episode_ranges_survive_the_command_line_parser():
    """draccus reads '10:20' as the YAML 1.1 base-60 integer 620; that is undone exactly."""
    assert normalize_episode_range("10:20") == "10:20"
    assert normalize_episode_range(620) == "10:20" and normalize_episode_range("320") == "5:20"
    assert normalize_episode_range("1120:1400") == "1120:1400"
    for bad in ("10", 605, "a:b", "5:5", "20:10", "1:2:3"):
        with pytest.raises(ConfigError, match="test_episodes"):
            normalize_episode_range(bad)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"with_action": False}, DatasetError, r"no 'action' feature"),
        ({"state_dim": 7}, DatasetError, r"'observation\.state' has shape \(7,\)"),
        (
            {"episode_len": 12},
            DatasetError,
            r"not a keyframe dataset \(fps 1, episodes of \[12\] frames\).*--policy\.mode=recovering",
        ),
        ({"fps": 20, "episode_len": 30}, DatasetError, r"not a keyframe dataset \(fps 20"),
        ({"nan_at": (2, 7)}, DatasetError, r"observation\.environment_state .*(NaN|non-finite).*episode 2, frame 7"),
    ],
)
def test_train_fast_rejects_wrong_datasets(tmp_path, kwargs, error, match):
    root = tmp_path / "bad"
    make_keyframe_dataset(root, n_episodes=3, **kwargs)
    with pytest.raises(error, match=match):
        train_fast(_cfg(root, tmp_path / "o", epochs=1))
    assert not (tmp_path / "o").exists()  # nothing written before the data are known to be good


def test_policy_rejects_non_keyframe_dataset_meta(tmp_path):
    from lerobot.policies.factory import make_policy

    root = tmp_path / "long"
    make_keyframe_dataset(root, n_episodes=2, episode_len=12)
    ds = LeRobotDataset(REPO_ID, root=root, video_backend="pyav")
    with pytest.raises(DatasetError, match="not a keyframe dataset.*--policy.mode=recovering"):
        make_policy(PnpLstmConfig(), ds_meta=ds.meta)


# ---- stock lerobot-train: every sample is one whole episode -------------------------------------


def test_lerobot_train_samples_are_whole_episodes(dataset_root):
    """With the policy's windows and drop_n_last_frames, LeRobot's EpisodeAwareSampler yields each episode's
    first frame once per epoch, and every window (also the eval split's, at any frame) holds the episode."""
    from lerobot.datasets import EpisodeAwareSampler, resolve_delta_timestamps
    from lerobot.policies.factory import make_policy

    plain = LeRobotDataset(REPO_ID, root=dataset_root, video_backend="pyav")
    torch.manual_seed(0)
    policy = make_policy(PnpLstmConfig(hidden_size=16), ds_meta=plain.meta)
    policy.eval()
    delta = resolve_delta_timestamps(policy.config, plain.meta)
    ds = LeRobotDataset(REPO_ID, root=dataset_root, delta_timestamps=delta, video_backend="pyav")
    sampler = EpisodeAwareSampler(  # as lerobot_train.py builds it
        ds.meta.episodes["dataset_from_index"],
        ds.meta.episodes["dataset_to_index"],
        drop_n_last_frames=getattr(policy.config, "drop_n_last_frames", 0),
        shuffle=True,
        seed=0,
    )
    picked = sorted(int(ds[i]["frame_index"]) * 1000 + int(ds[i]["episode_index"]) for i in sampler)
    assert picked == list(range(N_EPISODES))  # frame 0 of every episode, once

    pre, _ = make_pre_post_processors(policy.config, dataset_stats=ds.meta.stats)
    _, data = load_keyframe_data(REPO_ID, dataset_root)
    n_ep = 3
    full = pre(data.batch(torch.arange(n_ep)))
    full = {k: full[k] for k in (OBS_STATE, OBS_ENV, ACTION)}
    full_loss, _ = policy.forward(full)
    keys = (OBS_STATE, OBS_ENV, ACTION, f"{OBS_STATE}_is_pad", f"{OBS_ENV}_is_pad", f"{ACTION}_is_pad")
    for frame in (0, 4, T - 1):  # training samples (frame 0) and eval-split samples (any frame)
        items = [ds[e * T + frame] for e in range(n_ep)]
        batch = pre({k: torch.stack([it[k] for it in items]) for k in keys})
        assert batch[OBS_STATE].shape == (n_ep, 2 * T - 1, 8)
        loss, _ = policy.forward(batch)
        torch.testing.assert_close(loss, full_loss)


@pytest.mark.slow
def test_lerobot_train_cli(dataset_root, tmp_path):
    out = tmp_path / "train"
    cmd = [
        str(Path(sys.executable).with_name("lerobot-train")),
        f"--dataset.repo_id={REPO_ID}",
        f"--dataset.root={dataset_root}",
        "--dataset.video_backend=pyav",
        "--policy.type=pnp_lstm",
        "--policy.hidden_size=16",
        "--steps=3",
        "--batch_size=8",
        "--num_workers=0",
        "--save_freq=3",
        "--log_freq=1",
        f"--output_dir={out}",
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "HF_HUB_OFFLINE": "1"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO_ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "mse_pick" in proc.stdout + proc.stderr
    pm = out / "checkpoints" / "last" / "pretrained_model"
    policy = PnpLstmPolicy.from_pretrained(pm)
    assert policy.config.hidden_size == 16 and policy.config.dataset_fps == 1
    obs = {OBS_STATE: torch.zeros(2, 8), OBS_ENV: torch.zeros(2, 3)}
    assert torch.isfinite(policy.select_action(obs)).all()

    # Resume, as LeRobot documents it, continues the same run to a larger step budget (the entry point again, in a
    # process forked from a warm interpreter: tests/zygote.py).
    resume = [cmd[0], f"--config_path={pm / 'train_config.json'}", "--resume=true", "--steps=5"]
    proc = zygote.run(resume, tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert (out / "checkpoints" / "000005" / "pretrained_model" / "model.safetensors").is_file()
    assert json.loads((out / "checkpoints" / "last" / "training_state" / "training_step.json").read_text())["step"] == 5


# ---- lerobot-pnp train: bad input is one clear line ---------------------------------------------


def _train_cli(*args: str, capsys) -> tuple[int, str]:
    """``lerobot-pnp train`` through its entry point (``cli.main``, what the console script calls): exit code, stderr.
    The executable itself runs in test_packaging and test_readme_quickstart."""
    from lerobot_pnp.cli import main

    capsys.readouterr()
    code = main(["train", "--progress", "false", *args])
    return code, capsys.readouterr().err


def _assert_one_line_error(result: tuple[int, str], match: str, codes=(2,)) -> None:
    code, err = result
    lines = [line for line in err.splitlines() if line.strip() and "Warning" not in line]
    assert code in codes, (code, err[-2000:])
    assert "Traceback" not in err, err[-2000:]
    assert len(lines) == 1, err[-2000:]
    assert match in lines[0], lines[0]


def test_train_cli_rejects_bad_flags_before_any_work(dataset_root, tmp_path, capsys):
    """Each bad flag is refused before any work, in one line, exit 2."""
    from lerobot_pnp.cli import main

    ds = ["--dataset_repo_id", REPO_ID, "--dataset_root", str(dataset_root), "--output_dir", str(tmp_path / "o")]
    for flags, match in (
        (["--epochs", "0"], "epochs must be an integer >= 1, got 0"),
        (["--lr", "-0.1"], "lr must be a positive number, got -0.1"),
        (["--lr", "nan"], "lr must be a positive number"),
        (["--batch_size", "0"], "batch_size must be an integer >= 1"),
        (["--steps", "-5"], "steps must be an integer >= 1"),
        (["--test_episodes", "abc"], "test_episodes must be a range 'start:stop'"),
        (["--test_episodes", "20:10"], "test_episodes '20:10' is empty"),
        (["--policy.optimizer_lr", "-1"], "optimizer_lr must be > 0"),
        (["--policy.steps_per_subtask", "4"], "a keyframe episode has 10 frames"),
        (["--policy.push_to_hub", "true"], "policy.push_to_hub needs policy.repo_id"),
    ):
        assert main(["train", *ds, *flags]) == 2, flags
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and match in err, (flags, err)
    assert not (tmp_path / "o").exists()


def test_push_to_hub_uploads_the_policy_its_processors_and_its_task(dataset_root, tmp_path, monkeypatch):
    """``--policy.push_to_hub`` uploads what ``lerobot-train`` pushes (the Hub's API recorded here, not called):
    every file of the saved ``pretrained_model`` (the weights, the config, both processors, and the task the data
    was recorded in where it records one) and a model card."""
    import huggingface_hub

    uploaded: dict[str, set[str]] = {}

    def create_repo(self, repo_id, **kwargs):
        return huggingface_hub.RepoUrl(f"https://huggingface.co/{repo_id}")

    def upload_folder(self, repo_id, folder_path, **kwargs):
        uploaded.setdefault(repo_id, set()).update(p.name for p in Path(folder_path).rglob("*") if p.is_file())
        return huggingface_hub.CommitInfo(f"https://huggingface.co/{repo_id}/commit/0", "", "", "0")

    monkeypatch.setattr(huggingface_hub.HfApi, "create_repo", create_repo)
    monkeypatch.setattr(huggingface_hub.HfApi, "upload_folder", upload_folder)
    monkeypatch.setattr(huggingface_hub.ModelCard, "validate", lambda self, *a, **k: None)  # a Hub call too
    policy = PnpLstmConfig(device="cpu", hidden_size=8, push_to_hub=True, repo_id="someone/pnp_lstm")
    train_fast(_cfg(dataset_root, tmp_path / "run", policy=policy, epochs=1, batch_size=8))
    files = uploaded["someone/pnp_lstm"]
    saved = {p.name for p in (tmp_path / "run/checkpoints/last/pretrained_model").iterdir()}
    assert saved <= files and {"model.safetensors", "policy_preprocessor.json", "README.md"} <= files, files


def test_train_cli_bad_input(dataset_root, tmp_path, capsys):
    """A run beside a user's file keeps it, and a second run there without --overwrite is refused in one line; a
    test range reaches the trainer as written; a range outside the dataset, found only while running, is one line."""
    from lerobot_pnp.cli import main

    ds = ["--dataset_repo_id", REPO_ID, "--dataset_root", str(dataset_root), "--progress", "false"]
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(["train", *ds, "--output_dir", str(out), "--epochs", "1"]) == 0
    assert main(["train", *ds, "--output_dir", str(out), "--epochs", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "already holds a training run" in err and "--overwrite" in err, err
    assert (out / "keep.txt").read_text() == "mine"

    # '10:20' reaches the trainer as the range it is (not the base-60 number 620).
    assert main(["train", *ds, "--output_dir", str(tmp_path / "ok"), "--epochs", "1", "--test_episodes", "10:20"]) == 0
    err = json.loads((tmp_path / "ok" / "test_keyframe_error.json").read_text())
    assert err["n_test_episodes"] == 10 and err["split"] == "override test=10:20"
    _assert_one_line_error(
        _train_cli(*ds, "--output_dir", str(tmp_path / "o2"), "--test_episodes", "30:50", capsys=capsys),
        "outside the dataset's episodes 0:40",
    )


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"fps": 20, "episode_len": 30}, "is not a keyframe dataset (fps 20"),
        ({"nan_at": (1, 3)}, "episode 1, frame 3"),
    ],
)
def test_train_cli_bad_datasets(tmp_path, kwargs, match, capsys):
    root = tmp_path / "bad"
    make_keyframe_dataset(root, n_episodes=3, **kwargs)
    result = _train_cli(
        "--dataset_repo_id", REPO_ID, "--dataset_root", str(root), "--output_dir", str(tmp_path / "o"), capsys=capsys
    )
    _assert_one_line_error(result, match)
    assert len(result[1]) < 1000  # names the place, no dumped batch


def test_overwrite_replaces_only_what_a_training_run_recorded(dataset_root, tmp_path):
    """The run records its entries in the folder's manifest; ``--overwrite`` deletes those and refuses a file of
    the user's even where it has a run file's name (``loss_curve.csv``)."""
    from lerobot_pnp.outputs import MANIFEST_FILE

    out = tmp_path / "run"
    cfg = dict(policy=PnpLstmConfig(device="cpu", hidden_size=8), epochs=1, batch_size=8)
    train_fast(_cfg(dataset_root, out, **cfg))
    recorded = set(json.loads((out / MANIFEST_FILE).read_text())["owners"]["lerobot-pnp train"])
    assert recorded == {"checkpoints", "train_fast_config.json", "loss_curve.csv", "loss_curve.png",
                        "test_keyframe_error.json"}  # fmt: skip
    train_fast(_cfg(dataset_root, out, overwrite=True, seed=5, **cfg))
    assert json.loads((out / "train_fast_config.json").read_text())["seed"] == 5

    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "loss_curve.csv").write_text("my own curve")
    with pytest.raises(ConfigError, match="loss_curve.csv.*did not write"):
        train_fast(_cfg(dataset_root, mine, overwrite=True, **cfg))
    assert (mine / "loss_curve.csv").read_text() == "my own curve"
