"""Tests of the ``pnp_lstm`` policy (lerobot_pnp/policy) and its fast training path (lerobot_pnp/train_fast.py).

A small synthetic keyframe dataset (40 episodes x 10 frames, LeRobotDataset v3) with learnable dynamics
stands in for the simulator's data: the next keyframe is a deterministic function of the object position
and the phase, so the planner must know the phase (memory / subtask net) to predict it.
"""

from __future__ import annotations

import ast
import json
import math
import os
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
import pytest
import torch

torch.set_num_threads(1)

from lerobot.configs import FeatureType, PolicyFeature  # noqa: E402
from lerobot.datasets import LeRobotDataset  # noqa: E402
from lerobot.datasets.io_utils import write_info  # noqa: E402
from lerobot.policies.factory import get_policy_class, make_policy_config, make_pre_post_processors  # noqa: E402

from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy  # noqa: E402
from lerobot_pnp.policy.modeling_pnp_lstm import SubtaskLSTM  # noqa: E402
from lerobot_pnp.train_fast import (  # noqa: E402
    TrainFastConfig,
    load_keyframe_data,
    split_episodes,
    train_fast,
)

REPO_ROOT = Path(__file__).resolve().parents[1]
OBS_STATE, OBS_ENV, ACTION = "observation.state", "observation.environment_state", "action"
STATE_NAMES = ["left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2", "gripper"]
N_EPISODES, N_TRAIN = 40, 32
T = 10


def _features(state_dim: int = 8, action_dim: int = 8, with_action: bool = True) -> dict:
    feats = {
        OBS_STATE: {"dtype": "float32", "shape": (state_dim,), "names": STATE_NAMES[:state_dim]},
        OBS_ENV: {"dtype": "float32", "shape": (3,), "names": ["object_x", "object_y", "object_z"]},
        "phase.index": {"dtype": "int64", "shape": (1,), "names": None},
        "phase.subtask": {"dtype": "int64", "shape": (1,), "names": None},
        "next.done": {"dtype": "bool", "shape": (1,), "names": None},
        "next.success": {"dtype": "bool", "shape": (1,), "names": None},
    }
    if with_action:
        feats[ACTION] = {"dtype": "float32", "shape": (action_dim,), "names": STATE_NAMES[:action_dim]}
    return feats


def _synthetic_episode(rng: np.random.Generator):
    """10 keyframes: states, object positions and actions (= next keyframe's joint targets + gripper)."""
    place = np.array([0.75, 0.0, -0.13])
    obj0 = np.array([rng.uniform(0.55, 0.85), rng.uniform(-0.25, 0.25), -0.13])
    w = np.linspace(-1.0, 1.0, 21).reshape(7, 3)

    def joints(o, k):
        return np.tanh(w @ (o - place) * (1 + 0.3 * k) + 0.1 * k)

    lift = np.array([0.0, 0.0, 0.1])
    q = [rng.uniform(-0.6, 0.6, 7), joints(obj0 + lift, 1), joints(obj0, 2)]
    q += [q[2].copy(), joints(obj0 + lift, 1)]  # close, retract
    q += [q[4].copy(), joints(place + lift, 3) + 0.3 * q[4], joints(place, 4) + 0.3 * q[4]]
    q += [q[7].copy(), joints(place + lift, 5)]
    grip = [1, 1, 1, 0, 0, 0, 0, 0, 1, 1]
    objs = [obj0] * 4 + [obj0 + lift] * 2 + [place + lift, place, place, place]
    states = [np.concatenate([q[k] + rng.normal(0, 0.005, 7), [grip[k]]]) for k in range(T)]
    acts = [np.concatenate([q[k + 1], [grip[k + 1]]]) for k in range(T - 1)]
    acts[4] = np.concatenate([q[4], [grip[4]]])  # pick retract holds (place start == pick retract)
    acts.append(np.concatenate([q[9], [grip[9]]]))  # place retract holds
    return states, objs, acts


def make_keyframe_dataset(
    root: Path,
    n_episodes: int = N_EPISODES,
    seed: int = 0,
    splits: dict | None = None,
    episode_len: int = T,
    state_dim: int = 8,
    with_action: bool = True,
    repo_id: str = "test/pnp_synth",
) -> LeRobotDataset:
    rng = np.random.default_rng(seed)
    ds = LeRobotDataset.create(
        repo_id,
        fps=1,
        features=_features(state_dim, with_action=with_action),
        root=root,
        robot_type="baxter",
        use_videos=False,
        video_backend="pyav",
    )
    for _ in range(n_episodes):
        states, objs, acts = _synthetic_episode(rng)
        for k in range(episode_len):
            frame = {
                OBS_STATE: states[k % T][:state_dim].astype(np.float32),
                OBS_ENV: objs[k % T].astype(np.float32),
                "phase.index": np.array([k % T]),
                "phase.subtask": np.array([(k % T) // 5]),
                "next.done": np.array([k == episode_len - 1]),
                "next.success": np.array([k == episode_len - 1]),
                "task": "Pick the cube and place it on the target.",
            }
            if with_action:
                frame[ACTION] = acts[k % T].astype(np.float32)
            ds.add_frame(frame)
        ds.save_episode()
    ds.finalize()
    if splits is not None:
        ds.meta.info.splits = dict(splits)
        write_info(ds.meta.info, ds.root)
    return ds


# ---- fixtures -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def dataset_root(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("pnp_ds") / "keyframes"
    make_keyframe_dataset(root, splits={"train": f"0:{N_TRAIN}", "test": f"{N_TRAIN}:{N_EPISODES}"})
    return root


@pytest.fixture(scope="module")
def trained(dataset_root, tmp_path_factory):
    out = tmp_path_factory.mktemp("pnp_train") / "run"
    cfg = TrainFastConfig(
        dataset_repo_id="test/pnp_synth",
        dataset_root=str(dataset_root),
        policy=PnpLstmConfig(device="cpu", hidden_size=32),
        epochs=80,
        batch_size=8,
        seed=0,
        output_dir=str(out),
        progress=False,
    )
    result = train_fast(cfg)
    return result, out


@pytest.fixture(scope="module")
def episodes(dataset_root):
    """Raw (unnormalised) episodes of the synthetic dataset as (E, 10, D) tensors."""
    _, data = load_keyframe_data("test/pnp_synth", dataset_root)
    return data


def _fresh_policy(**kw) -> PnpLstmPolicy:
    torch.manual_seed(0)
    cfg = PnpLstmConfig(device="cpu", hidden_size=kw.pop("hidden_size", 16), **kw)
    cfg.input_features = {
        OBS_STATE: PolicyFeature(FeatureType.STATE, (8,)),
        OBS_ENV: PolicyFeature(FeatureType.ENV, (3,)),
    }
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (8,))}
    policy = PnpLstmPolicy(cfg)
    policy.eval()
    return policy


def _norm_episodes(n: int = 6, seed: int = 0) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    return {
        OBS_STATE: torch.randn(n, T, 8, generator=g),
        OBS_ENV: torch.randn(n, T, 3, generator=g),
        ACTION: torch.randn(n, T, 8, generator=g),
    }


def _rollout(policy, eps: dict[str, torch.Tensor], steps: int = T, rows=None) -> torch.Tensor:
    """select_action over the episodes' frames, (B, steps, A)."""
    rows = slice(None) if rows is None else rows
    out = []
    for k in range(steps):
        kk = min(k, T - 1)
        out.append(policy.select_action({OBS_STATE: eps[OBS_STATE][rows, kk], OBS_ENV: eps[OBS_ENV][rows, kk]}))
    return torch.stack(out, dim=1)


# ---- LeRobot integration ------------------------------------------------------------------------


def test_factory_finds_plugin_classes():
    assert get_policy_class("pnp_lstm") is PnpLstmPolicy
    cfg = make_policy_config("pnp_lstm")
    assert isinstance(cfg, PnpLstmConfig)
    assert type(cfg).__module__ == "lerobot_pnp.policy.configuration_pnp_lstm"
    assert cfg.device == "cpu" and cfg.push_to_hub is False
    assert cfg.observation_delta_indices == list(range(-9, 1))
    assert cfg.action_delta_indices == list(range(-9, 1))
    assert cfg.reward_delta_indices is None
    cfg.input_features = {
        OBS_STATE: PolicyFeature(FeatureType.STATE, (8,)),
        OBS_ENV: PolicyFeature(FeatureType.ENV, (3,)),
    }
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (8,))}
    pre, post = make_pre_post_processors(cfg, dataset_stats=None)
    assert pre.name == "policy_preprocessor" and post.name == "policy_postprocessor"


def test_config_validation():
    with pytest.raises(ValueError, match="num_layers"):
        PnpLstmConfig(num_layers=3)
    with pytest.raises(ValueError, match="shared_network"):
        PnpLstmConfig(carry_hidden_across_subtasks=True)
    with pytest.raises(ValueError, match="lr_scheduler"):
        PnpLstmConfig(lr_scheduler="step")
    assert PnpLstmConfig().get_scheduler_preset() is None
    assert PnpLstmConfig(lr_scheduler="cosine").get_scheduler_preset() is not None
    cfg = PnpLstmConfig()
    cfg.input_features = {OBS_STATE: PolicyFeature(FeatureType.STATE, (8,))}
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (8,))}
    with pytest.raises(ValueError, match="environment_state"):
        PnpLstmPolicy(cfg)


def test_policy_imports_no_simulator():
    """The policy package knows tensors and LeRobot features only."""
    banned = ("mujoco", "gymnasium", "gym", "lerobot_pnp")
    for path in (REPO_ROOT / "lerobot_pnp" / "policy").glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                mods = [node.module or ""] if node.level == 0 else []
            else:
                continue
            for m in mods:
                assert m.split(".")[0] not in banned, f"{path.name} imports {m}"


def test_windowed_batches_match_full_episodes(dataset_root):
    """lerobot-train's windows: normalised correctly, shifted to frame 0, balanced loss == full-episode loss."""
    from lerobot.datasets import resolve_delta_timestamps
    from lerobot.policies.factory import make_policy

    plain = LeRobotDataset("test/pnp_synth", root=dataset_root, video_backend="pyav")
    torch.manual_seed(0)
    policy = make_policy(PnpLstmConfig(hidden_size=16), ds_meta=plain.meta)  # features from the dataset
    policy.eval()
    delta = resolve_delta_timestamps(policy.config, plain.meta)
    assert delta[OBS_STATE] == [float(k) for k in range(-9, 1)]  # fps = 1: delta indices are seconds
    ds = LeRobotDataset("test/pnp_synth", root=dataset_root, delta_timestamps=delta, video_backend="pyav")
    pre, _ = make_pre_post_processors(policy.config, dataset_stats=ds.meta.stats)

    n_ep = 4
    windows = [ds[i] for i in range(n_ep * T)]  # every frame of the first episodes
    batch = {
        k: torch.stack([w[k] for w in windows])
        for k in (OBS_STATE, OBS_ENV, ACTION, f"{OBS_STATE}_is_pad", f"{OBS_ENV}_is_pad", f"{ACTION}_is_pad")
    }
    raw_state = batch[OBS_STATE].clone()
    assert batch[OBS_STATE].shape == (n_ep * T, T, 8) and batch[f"{OBS_STATE}_is_pad"].shape == (n_ep * T, T)
    nb = pre(batch)
    # The normaliser sees (B, T, D) and broadcasts the (D,) stats over B and T.
    stats = ds.meta.stats[OBS_STATE]
    expect = (raw_state - torch.as_tensor(stats["mean"]).float()) / (torch.as_tensor(stats["std"]).float() + 1e-8)
    torch.testing.assert_close(nb[OBS_STATE], expect)
    assert torch.equal(nb[f"{ACTION}_is_pad"], batch[f"{ACTION}_is_pad"])

    # Full episodes (the fast path) through the same pre-processor.
    full = {k: torch.stack([nb[k][e * T + T - 1] for e in range(n_ep)]) for k in (OBS_STATE, OBS_ENV, ACTION)}
    assert not torch.stack([batch[f"{OBS_STATE}_is_pad"][e * T + T - 1] for e in range(n_ep)]).any()
    with torch.no_grad():
        full_pred = policy.predict_sequence(full)
        for i in range(n_ep * T):
            e, t = divmod(i, T)
            win = {k: nb[k][i : i + 1] for k in nb if isinstance(nb[k], torch.Tensor) and nb[k].ndim >= 2}
            # After shifting, position k of the window is episode frame k: same predictions as the full episode.
            x = policy._gather_inputs(win, sequence=True)
            n_pad = int(win[f"{OBS_STATE}_is_pad"].sum())
            assert n_pad == T - 1 - t
            pred = policy._run_sequence(torch.roll(x, -n_pad, dims=1))
            torch.testing.assert_close(pred[0, : t + 1], full_pred[e, : t + 1])
        # Averaged over every window of every episode, the balanced window loss is the full-episode MSE.
        win_loss, _ = policy.forward({k: v for k, v in nb.items() if isinstance(v, torch.Tensor)})
        full_loss, _ = policy.forward(full)
        torch.testing.assert_close(win_loss, full_loss)
        per_sample, _ = policy.forward({k: v for k, v in nb.items() if isinstance(v, torch.Tensor)}, reduction="none")
        assert per_sample.shape == (n_ep * T,)


def test_forward_rejects_bad_pad_mask():
    policy = _fresh_policy()
    b = _norm_episodes(2)
    pad = torch.zeros(2, T, dtype=torch.bool)
    pad[0, -1] = True  # padding at the end of a window: not produced by delta indices -9..0
    with pytest.raises(ValueError, match="Padding"):
        policy.forward({**b, f"{OBS_STATE}_is_pad": pad, f"{ACTION}_is_pad": pad})
    with pytest.raises(ValueError, match="longer than an episode"):
        policy.forward({k: torch.cat([v, v], dim=1) for k, v in b.items()})


# ---- training and checkpoints -------------------------------------------------------------------


def test_train_fast_reduces_loss_and_writes_outputs(trained):
    result, out = trained
    h0 = result.history[0]
    assert result.final_train_mse < 0.05 * h0["train_mse"], (h0, result.final_train_mse)
    assert result.final_test_mse < 0.2 * h0["test_mse"], (h0, result.final_test_mse)
    pm = out / "checkpoints" / "last" / "pretrained_model"
    assert (out / "checkpoints" / "last").is_symlink()
    for name in (
        "config.json",
        "model.safetensors",
        "train_config.json",
        "policy_preprocessor.json",
        "policy_postprocessor.json",
    ):
        assert (pm / name).is_file(), name
    assert list(pm.glob("policy_preprocessor_step_*_normalizer_processor.safetensors"))
    assert json.loads((pm / "config.json").read_text())["type"] == "pnp_lstm"
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


def test_save_load_roundtrip_identical_actions(trained, episodes):
    result, _ = trained
    path = result.checkpoint_dir
    a = PnpLstmPolicy.from_pretrained(path)
    b = PnpLstmPolicy.from_pretrained(path)
    cfg = PnpLstmConfig.from_pretrained(path)
    cfg.pretrained_path = path  # lerobot#4647: processors need the path to get their stats
    pre, post = make_pre_post_processors(cfg, pretrained_path=str(path))
    rows = torch.arange(N_TRAIN, N_EPISODES)
    raw = episodes.batch(rows)
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
    # Same weights as the in-memory policy that was trained, and sensible predictions in raw units.
    err = (acts[0][..., :7] - raw[ACTION][..., :7]).abs().mean() * 180 / math.pi
    assert float(err) < 5.0
    sd_a = a.state_dict()
    for k, v in PnpLstmPolicy.from_pretrained(path).state_dict().items():
        assert torch.equal(v, sd_a[k])


def test_train_fast_refuses_existing_output_dir(trained, dataset_root):
    _, out = trained
    with pytest.raises(FileExistsError):
        train_fast(
            TrainFastConfig(
                dataset_repo_id="test/pnp_synth",
                dataset_root=str(dataset_root),
                output_dir=str(out),
                epochs=1,
                progress=False,
            )
        )


# ---- inference ----------------------------------------------------------------------------------


def test_select_action_matches_teacher_forced_sequence():
    for kw in (
        {},
        {"shared_network": True},
        {"shared_network": True, "carry_hidden_across_subtasks": True},
        {"recurrent": False},
        {"num_layers": 2, "dropout": 0.1},
    ):
        policy = _fresh_policy(**kw)
        eps = _norm_episodes(5)
        with torch.no_grad():
            seq = policy.predict_sequence(eps)
        policy.reset()
        steps = _rollout(policy, eps)
        torch.testing.assert_close(steps, seq, msg=str(kw))


def test_reset_clears_hidden_state():
    policy = _fresh_policy()
    fresh = _fresh_policy()
    eps = _norm_episodes(3)
    _rollout(policy, eps, steps=3)
    assert policy._step is not None and int(policy._step[0]) == 3
    policy.reset()
    assert policy._step is None and policy._hidden is None and policy._last_action is None
    first = _rollout(policy, eps, steps=1)
    torch.testing.assert_close(first, _rollout(fresh, eps, steps=1))
    # Without reset, the same observation gives a different action (memory + step counter).
    policy.reset()
    _rollout(policy, eps, steps=2)
    again = policy.select_action({OBS_STATE: eps[OBS_STATE][:, 0], OBS_ENV: eps[OBS_ENV][:, 0]})
    assert not torch.allclose(again, first[:, 0])


def test_network_switch_at_step_five():
    policy = _fresh_policy()
    assert len(policy.subtask_nets) == 2 and all(isinstance(n, SubtaskLSTM) for n in policy.subtask_nets)
    eps = _norm_episodes(4)
    acts = _rollout(policy, eps)
    x = torch.cat([eps[OBS_STATE], eps[OBS_ENV]], dim=-1)
    with torch.no_grad():
        # Step 5 = the place net from a zero hidden state on frame 5 alone.
        place5, _ = policy.subtask_nets[1](x[:, 5:6])
        pick5, _ = policy.subtask_nets[0](x[:, 5:6])
        pick0, _ = policy.subtask_nets[0](x[:, 0:1])
    torch.testing.assert_close(acts[:, 5], place5[:, 0])
    torch.testing.assert_close(acts[:, 0], pick0[:, 0])
    assert not torch.allclose(place5, pick5)  # the two nets are different networks
    # Steps 0..4 do not influence the place subtask.
    other = {k: v.clone() for k, v in eps.items()}
    other[OBS_STATE][:, :5] += 1.0
    other[OBS_ENV][:, :5] -= 1.0
    policy.reset()
    acts2 = _rollout(policy, other)
    assert not torch.allclose(acts2[:, :5], acts[:, :5])
    torch.testing.assert_close(acts2[:, 5:], acts[:, 5:])


def test_holds_last_action_after_the_last_keyframe():
    policy = _fresh_policy()
    acts = _rollout(policy, _norm_episodes(2), steps=T + 3)
    for k in range(T, T + 3):
        torch.testing.assert_close(acts[:, k], acts[:, T - 1])


def test_batched_select_action_equals_per_env():
    policy = _fresh_policy()
    eps = _norm_episodes(6)
    batched = _rollout(policy, eps)
    for i in range(6):
        policy.reset()
        single = _rollout(policy, eps, rows=slice(i, i + 1))
        torch.testing.assert_close(single[0], batched[i], rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match="Batch size changed"):
        policy.select_action({OBS_STATE: eps[OBS_STATE][:, 0], OBS_ENV: eps[OBS_ENV][:, 0]})


def test_select_action_under_inference_mode_then_without():
    policy = _fresh_policy()
    eps = _norm_episodes(2)
    obs = {OBS_STATE: eps[OBS_STATE][:, 0], OBS_ENV: eps[OBS_ENV][:, 0]}
    with torch.inference_mode():
        policy.select_action(obs)
    policy.select_action(obs)  # caches created under inference_mode are not modified in place
    assert policy.predict_action_chunk(obs).shape == (2, 1, 8)


def test_non_finite_observation_raises():
    policy = _fresh_policy()
    obs = {OBS_STATE: torch.zeros(2, 8), OBS_ENV: torch.zeros(2, 3)}
    bad = {**obs, OBS_STATE: obs[OBS_STATE].clone()}
    bad[OBS_STATE][1, 3] = float("nan")
    with pytest.raises(ValueError, match=r"observation\.state.*non-finite"):
        policy.select_action(bad)
    bad = {**obs, OBS_ENV: obs[OBS_ENV].clone()}
    bad[OBS_ENV][0, 0] = float("inf")
    with pytest.raises(ValueError, match=r"observation\.environment_state.*non-finite"):
        policy.select_action(bad)


def test_mismatched_features_raise():
    policy = _fresh_policy()
    with pytest.raises(ValueError, match=r"observation\.state.*shape"):
        policy.select_action({OBS_STATE: torch.zeros(2, 7), OBS_ENV: torch.zeros(2, 3)})
    with pytest.raises(ValueError, match=r"observation\.environment_state.*missing"):
        policy.select_action({OBS_STATE: torch.zeros(2, 8)})
    with pytest.raises(ValueError, match="leading shape"):
        policy.select_action({OBS_STATE: torch.zeros(2, 8), OBS_ENV: torch.zeros(3, 3)})
    b = _norm_episodes(2)
    with pytest.raises(ValueError, match="'action' has shape"):
        policy.forward({**b, ACTION: b[ACTION][..., :7]})


def test_memoryless_variant_has_no_memory():
    policy = _fresh_policy(recurrent=False)
    ref = _fresh_policy()
    assert sum(p.numel() for p in policy.parameters()) == sum(p.numel() for p in ref.parameters())
    eps = _norm_episodes(3)
    acts = _rollout(policy, eps)
    other = {k: v.clone() for k, v in eps.items()}
    other[OBS_STATE][:, 1] += 1.0
    policy.reset()
    acts2 = _rollout(policy, other)
    torch.testing.assert_close(acts2[:, 2:], acts[:, 2:])  # only step 1's own output changes


# ---- dataset validation and splits --------------------------------------------------------------


def test_train_fast_config_from_lerobot_train_json():
    cfg = TrainFastConfig.from_train_config(REPO_ROOT / "configs" / "train_pnp_lstm.json", epochs=3)
    raw = json.loads((REPO_ROOT / "configs" / "train_pnp_lstm.json").read_text())
    assert cfg.dataset_repo_id == raw["dataset"]["repo_id"] and cfg.batch_size == raw["batch_size"]
    assert isinstance(cfg.policy, PnpLstmConfig) and cfg.epochs == 3
    for key, value in raw["policy"].items():
        if key != "type":
            assert getattr(cfg.policy, key) == value, key


def test_split_episodes():
    assert split_episodes({"train": "0:8", "test": "8:10"}, 10)[:2] == (list(range(8)), [8, 9])
    train, test, source = split_episodes({"train": "0:10"}, 10)
    assert (train, test) == (list(range(8)), [8, 9]) and "fallback" in source
    assert split_episodes({}, 10, test_override="0:2")[:2] == (list(range(2, 10)), [0, 1])
    with pytest.raises(ValueError):
        split_episodes({"test": "0:20"}, 10)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"with_action": False}, r"no 'action' feature"),
        ({"state_dim": 7}, r"'observation\.state' has shape \(7,\)"),
        ({"episode_len": 12}, r"not a keyframe dataset"),
    ],
)
def test_train_fast_rejects_wrong_datasets(tmp_path, kwargs, match):
    root = tmp_path / "bad"
    make_keyframe_dataset(root, n_episodes=3, **kwargs)
    cfg = TrainFastConfig(
        dataset_repo_id="test/pnp_synth",
        dataset_root=str(root),
        output_dir=str(tmp_path / "o"),
        epochs=1,
        progress=False,
    )
    with pytest.raises(ValueError, match=match):
        train_fast(cfg)


def test_policy_rejects_non_keyframe_dataset_meta(tmp_path):
    from lerobot.policies.factory import make_policy

    root = tmp_path / "long"
    make_keyframe_dataset(root, n_episodes=2, episode_len=12)
    ds = LeRobotDataset("test/pnp_synth", root=root, video_backend="pyav")
    with pytest.raises(ValueError, match="Not a keyframe dataset"):
        make_policy(PnpLstmConfig(), ds_meta=ds.meta)


# ---- the real lerobot-train CLI -----------------------------------------------------------------


def _plugin_installed() -> bool:
    from importlib.metadata import PackageNotFoundError, distribution

    try:
        distribution("lerobot_policy_pnp_lstm")
        return True
    except PackageNotFoundError:
        return False


@pytest.mark.slow
def test_lerobot_train_cli(dataset_root, tmp_path):
    out = tmp_path / "train"
    exe = Path(sys.executable).with_name("lerobot-train")
    cmd = [
        str(exe),
        "--dataset.repo_id=test/pnp_synth",
        f"--dataset.root={dataset_root}",
        "--dataset.video_backend=pyav",
        "--policy.type=pnp_lstm",
        "--policy.device=cpu",
        "--policy.push_to_hub=false",
        "--policy.hidden_size=16",
        "--steps=3",
        "--batch_size=8",
        "--num_workers=0",
        "--save_freq=3",
        "--log_freq=1",
        f"--output_dir={out}",
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "HF_HUB_OFFLINE": "1"}
    if not _plugin_installed():  # not pip-installed: let lerobot import the package by path
        cmd.insert(1, "--policy.discover_packages_path=lerobot_pnp")
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO_ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "mse_pick" in proc.stdout + proc.stderr
    pm = out / "checkpoints" / "last" / "pretrained_model"
    assert (pm / "train_config.json").is_file()
    policy = PnpLstmPolicy.from_pretrained(pm)
    assert policy.config.hidden_size == 16
    obs = {OBS_STATE: torch.zeros(2, 8), OBS_ENV: torch.zeros(2, 3)}
    assert torch.isfinite(policy.select_action(obs)).all()


def test_loading_a_checkpoint_for_other_features_names_the_mismatch(trained):
    """make_policy swaps in the env's output features; a different action size must fail clearly."""
    from lerobot.configs import FeatureType, PolicyFeature

    path = trained[0].checkpoint_dir
    cfg = PnpLstmConfig.from_pretrained(path)
    cfg.output_features = {"action": PolicyFeature(FeatureType.ACTION, (14,))}
    with pytest.raises(ValueError, match=r"trained with action of shape \(8,\), but the env/dataset provides \(14,\)"):
        PnpLstmPolicy.from_pretrained(path, config=cfg)
    assert PnpLstmPolicy.from_pretrained(path, config=PnpLstmConfig.from_pretrained(path)) is not None


def test_train_fast_on_a_missing_local_dataset_is_a_clear_error(tmp_path):
    """A wrong --dataset_root must not fall back to downloading repo_id from the Hub."""
    from lerobot_pnp.errors import DatasetError

    cfg = TrainFastConfig(
        dataset_repo_id="local/nothing",
        dataset_root=str(tmp_path / "missing"),
        epochs=1,
        output_dir=str(tmp_path / "out"),
        progress=False,
    )
    with pytest.raises(DatasetError, match="no dataset at"):
        train_fast(cfg)
    assert not (tmp_path / "out").exists()
