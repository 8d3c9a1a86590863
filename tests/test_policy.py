"""Tests of the ``pnp_lstm`` policy (lerobot_pnp/policy): config, network, inference, processors, checkpoints.

The training paths (fast path, ``lerobot-train`` windows, the ``lerobot-pnp train`` CLI) are tested in
``test_train_fast.py``.
"""

from __future__ import annotations

import ast
import json
import logging
from pathlib import Path

import pytest
import torch
from torch import nn

torch.set_num_threads(1)

from keyframe_synth import ACTION, OBS_ENV, OBS_STATE, T  # noqa: E402
from lerobot.configs import FeatureType, PolicyFeature  # noqa: E402
from lerobot.policies.factory import get_policy_class, make_policy_config, make_pre_post_processors  # noqa: E402
from safetensors.torch import load_file, save_file  # noqa: E402

from lerobot_pnp.errors import ConfigError, DatasetError, PolicyError  # noqa: E402
from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy, make_pnp_lstm_pre_post_processors  # noqa: E402
from lerobot_pnp.policy.clocked import PnpLstm, SubtaskLSTM  # noqa: E402
from lerobot_pnp.policy.planner import Planner  # noqa: E402

REPO_ROOT = Path(__file__).resolve().parents[1]


def _config(**kw) -> PnpLstmConfig:
    cfg = PnpLstmConfig(device="cpu", hidden_size=kw.pop("hidden_size", 16), **kw)
    cfg.input_features = {
        OBS_STATE: PolicyFeature(FeatureType.STATE, (8,)),
        OBS_ENV: PolicyFeature(FeatureType.ENV, (3,)),
    }
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (8,))}
    return cfg


def _fresh_policy(**kw) -> PnpLstmPolicy:
    torch.manual_seed(0)
    policy = PnpLstmPolicy(_config(**kw))
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


def _stats() -> dict:
    def s(d):
        return {"mean": torch.zeros(d), "std": torch.ones(d), "min": -torch.ones(d), "max": torch.ones(d)}

    return {OBS_STATE: s(8), OBS_ENV: s(3), ACTION: s(8)}


# ---- LeRobot integration ------------------------------------------------------------------------


def test_factory_finds_plugin_classes():
    assert get_policy_class("pnp_lstm") is PnpLstmPolicy
    cfg = make_policy_config("pnp_lstm")
    assert isinstance(cfg, PnpLstmConfig)
    assert type(cfg).__module__ == "lerobot_pnp.policy.configuration_pnp_lstm"
    assert cfg.device == "cpu" and cfg.push_to_hub is False
    # Every window holds its whole episode; the sampler picks each episode's first frame only.
    assert cfg.observation_delta_indices == list(range(-9, 10))
    assert cfg.action_delta_indices == list(range(-9, 10))
    assert cfg.drop_n_last_frames == 9
    assert cfg.reward_delta_indices is None
    cfg.input_features = _config().input_features
    cfg.output_features = _config().output_features
    pre, post = make_pre_post_processors(cfg, dataset_stats=None)
    assert pre.name == "policy_preprocessor" and post.name == "policy_postprocessor"


def test_policy_wraps_a_plain_network():
    """LeRobot's ACTPolicy / ACT split: the network is a plain nn.Module with all the weights."""
    policy = _fresh_policy()
    assert isinstance(policy.model, PnpLstm) and not hasattr(PnpLstm, "select_action")
    for planner in (policy.model, _fresh_policy(mode="recovering").model):  # the one interface of both planners
        assert isinstance(planner, Planner) and isinstance(planner, nn.Module)
    assert {n for n, _ in policy.named_parameters()} == {"model." + n for n, _ in policy.model.named_parameters()}
    x = torch.randn(3, T, 11)
    with torch.no_grad():
        torch.testing.assert_close(
            policy.model(x), policy.predict_sequence({OBS_STATE: x[..., :8], OBS_ENV: x[..., 8:]})
        )


def test_config_validation():
    for kwargs, match in (
        ({"num_layers": 3}, "num_layers"),
        ({"carry_hidden_across_subtasks": True}, "shared_network"),
        ({"lr_scheduler": "step"}, "lr_scheduler"),
        ({"optimizer_lr": -1e-3}, "optimizer_lr"),
        ({"dataset_fps": 0}, "dataset_fps"),
    ):
        with pytest.raises(ConfigError, match=match):
            PnpLstmConfig(**kwargs)
    assert PnpLstmConfig().get_scheduler_preset() is None
    assert PnpLstmConfig(lr_scheduler="cosine").get_scheduler_preset() is not None
    cfg = PnpLstmConfig()
    cfg.input_features = {OBS_STATE: PolicyFeature(FeatureType.STATE, (8,))}
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (8,))}
    with pytest.raises(ConfigError, match="environment_state"):
        PnpLstmPolicy(cfg)


def test_every_config_field_is_documented():
    import dataclasses

    from draccus.wrappers import docstring

    # the forms draccus (lerobot-train --help) shows: a docstring below the field or a comment above it
    own = [f.name for f in dataclasses.fields(PnpLstmConfig) if f.name in PnpLstmConfig.__annotations__]
    assert len(own) > 15
    for name in own:
        assert docstring.get_preferred_help_text(docstring.get_attribute_docstring(PnpLstmConfig, name)), name


def test_policy_imports_no_simulator():
    """The policy package knows tensors and LeRobot features only (and the package's error classes)."""
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
                if m != "lerobot_pnp.errors":
                    assert m.split(".")[0] not in banned, f"{path.name} imports {m}"


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


def test_reset_clears_the_episode_state():
    policy = _fresh_policy()
    fresh = _fresh_policy()
    eps = _norm_episodes(3)
    _rollout(policy, eps, steps=3)
    assert policy._state.step == 3
    policy.reset()
    assert policy._state is None
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


def test_a_long_episode_warns_about_the_control_mode(caplog):
    """A keyframe policy stepped far past its episode (a dense env) says so once, instead of failing silently."""
    policy = _fresh_policy()
    with caplog.at_level(logging.WARNING, logger="lerobot_pnp.policy.clocked"):
        _rollout(policy, _norm_episodes(1), steps=T)
        assert not caplog.records
        _rollout(policy, _norm_episodes(1), steps=6 * T)
    assert len(caplog.records) == 1 and "control_mode dense" in caplog.records[0].getMessage()


def test_check_env_fps():
    cfg = PnpLstmConfig(dataset_fps=1)
    cfg.check_env_fps(1)
    cfg.check_env_fps(None)
    with pytest.raises(PolicyError, match="trained on a 1 fps dataset.*env runs at 20 fps"):
        cfg.check_env_fps(20)
    PnpLstmConfig().check_env_fps(20)  # not recorded (older checkpoints): nothing to compare


def test_batched_select_action_equals_per_env():
    policy = _fresh_policy()
    eps = _norm_episodes(6)
    batched = _rollout(policy, eps)
    for i in range(6):
        policy.reset()
        single = _rollout(policy, eps, rows=slice(i, i + 1))
        torch.testing.assert_close(single[0], batched[i], rtol=1e-5, atol=1e-6)
    with pytest.raises(PolicyError, match="batch size changed"):
        policy.select_action({OBS_STATE: eps[OBS_STATE][:, 0], OBS_ENV: eps[OBS_ENV][:, 0]})


def test_select_action_under_inference_mode_then_without():
    policy = _fresh_policy()
    eps = _norm_episodes(2)
    obs = {OBS_STATE: eps[OBS_STATE][:, 0], OBS_ENV: eps[OBS_ENV][:, 0]}
    with torch.inference_mode():
        policy.select_action(obs)
    policy.select_action(obs)  # caches created under inference_mode are not modified in place
    assert policy.predict_action_chunk(obs).shape == (2, 1, 8)


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


# ---- training loss on windows -------------------------------------------------------------------


def test_window_loss_equals_whole_episode_loss_wherever_the_window_starts():
    """A window of frames -(T-1)..T-1 around any sampled frame holds the whole episode: same loss, same info."""
    policy = _fresh_policy()
    eps = _norm_episodes(4)
    full_loss, full_info = policy.forward(eps)
    length = 2 * T - 1
    for sampled in (0, 3, T - 1):
        start = T - 1 - sampled  # window position of episode frame 0
        win, pad = {}, torch.ones(4, length, dtype=torch.bool)
        pad[:, start : start + T] = False
        for key, v in eps.items():
            w = torch.full((4, length, v.shape[-1]), 123.0)  # LeRobot clamps; any value must be ignored
            w[:, start : start + T] = v
            win[key] = w
            win[f"{key}_is_pad"] = pad
        loss, info = policy.forward(win)
        torch.testing.assert_close(loss, full_loss)
        assert info.keys() == full_info.keys() == {"mse_pick", "mse_place"}
    per_sample, _ = policy.forward(win, reduction="none")
    assert per_sample.shape == (4,)
    torch.testing.assert_close(per_sample.mean(), full_loss)


# ---- the processor: the one place that checks observations --------------------------------------


def test_processor_rejects_observations_that_do_not_fit():
    pre, _ = make_pnp_lstm_pre_post_processors(_config(), dataset_stats=_stats())
    good = {OBS_STATE: torch.zeros(2, 8), OBS_ENV: torch.zeros(2, 3)}
    assert pre(dict(good))[OBS_STATE].shape == (2, 8)
    with pytest.raises(PolicyError, match=r"'observation\.state' has shape \(2, 7\).*trained on \(8,\)"):
        pre({**good, OBS_STATE: torch.zeros(2, 7)})
    with pytest.raises(PolicyError, match=r"observation 'observation\.environment_state' is missing"):
        pre({OBS_STATE: torch.zeros(2, 8)})
    bad = good[OBS_ENV].clone()
    bad[1, 0] = float("inf")
    with pytest.raises(PolicyError, match=r"'observation\.environment_state' contains NaN or inf \(batch row 1\)"):
        pre({**good, OBS_ENV: bad})


def test_binary_gripper_snaps_only_the_gripper_and_survives_a_checkpoint(tmp_path):
    from lerobot.processor import PolicyProcessorPipeline
    from lerobot.processor.converters import policy_action_to_transition, transition_to_policy_action

    from lerobot_pnp import robot

    _, plain = make_pnp_lstm_pre_post_processors(_config(), dataset_stats=_stats())
    _, post = make_pnp_lstm_pre_post_processors(_config(binary_gripper=True), dataset_stats=_stats())
    action = torch.tensor([[0.1, -0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.24], [0.0] * 7 + [0.74]])
    torch.testing.assert_close(plain(action.clone()), action)  # the paper's default regresses the gripper
    snapped = post(action.clone())
    torch.testing.assert_close(snapped[:, :7], action[:, :7])
    assert snapped[:, 7].tolist() == [robot.GRIPPER_CLOSED, robot.GRIPPER_OPEN]
    post.save_pretrained(tmp_path)
    name = next(p.name for p in tmp_path.glob("*.json"))
    loaded = PolicyProcessorPipeline.from_pretrained(
        tmp_path, name, to_transition=policy_action_to_transition, to_output=transition_to_policy_action
    )
    assert loaded(action.clone())[:, 7].tolist() == [0.0, 1.0]


def test_processor_names_the_episode_and_frame_of_a_nan_in_a_dataset_batch():
    cfg = _config(dataset_fps=1)
    pre, _ = make_pnp_lstm_pre_post_processors(cfg, dataset_stats=_stats())
    length = 2 * T - 1
    batch = {
        OBS_STATE: torch.zeros(3, length, 8),
        OBS_ENV: torch.zeros(3, length, 3),
        ACTION: torch.zeros(3, length, 8),
        "episode_index": torch.tensor([4, 7, 9]),
        "timestamp": torch.tensor([0.0, 0.0, 0.0]),
        "index": torch.tensor([40, 70, 90]),
    }
    batch[ACTION][1, T - 1 + 6, 2] = float("nan")  # episode 7, frame 6 (window position of frame 0: T-1)
    with pytest.raises(DatasetError) as err:
        pre(batch)
    assert str(err.value).startswith("action contains NaN or inf in episode 7, frame 6")
    assert len(str(err.value)) < 200  # names the place, does not dump the batch
    # A NaN in frame 0 is also in the padded copies before it: the frame named is the real one.
    batch[ACTION][1] = 0.0
    batch[ACTION][2, :T, 0] = float("nan")
    batch[f"{ACTION}_is_pad"] = torch.arange(2 * T - 1).expand(3, -1) < T - 1
    with pytest.raises(DatasetError, match="action contains NaN or inf in episode 9, frame 0"):
        pre(batch)


# ---- checkpoints --------------------------------------------------------------------------------


def _save_checkpoint(policy: PnpLstmPolicy, path: Path) -> Path:
    policy.save_pretrained(path)
    return path


def test_checkpoints_written_before_the_network_split_still_load(tmp_path):
    """Old checkpoints stored the subtask nets at the policy's top level and had no dataset_fps."""
    policy = _fresh_policy()
    path = _save_checkpoint(policy, tmp_path / "old")
    weights = load_file(path / "model.safetensors")
    old = {k.removeprefix("model."): v for k, v in weights.items()}
    assert all(k.startswith("subtask_nets.") for k in old)
    save_file(old, path / "model.safetensors")
    config = json.loads((path / "config.json").read_text())
    config.pop("dataset_fps")
    (path / "config.json").write_text(json.dumps(config))

    loaded = PnpLstmPolicy.from_pretrained(path)
    eps = _norm_episodes(2)
    policy.reset()
    torch.testing.assert_close(_rollout(loaded, eps), _rollout(policy, eps))


@pytest.mark.parametrize(
    ("damage", "match"),
    [
        ("missing_folder", "no pnp_lstm checkpoint at|not a complete checkpoint"),
        ("no_weights", r"missing model\.safetensors"),
        ("corrupt_weights", "cannot read the weights"),
        ("wrong_weights", "do not fit this pnp_lstm config"),
        ("corrupt_config", "cannot read the policy config"),
    ],
)
def test_bad_checkpoints_are_one_clear_policy_error(tmp_path, damage, match):
    path = _save_checkpoint(_fresh_policy(), tmp_path / "ckpt")
    if damage == "missing_folder":
        path = tmp_path / "nothing" / "pretrained_model"
    elif damage == "no_weights":
        (path / "model.safetensors").unlink()
    elif damage == "corrupt_weights":
        (path / "model.safetensors").write_bytes(b"not a safetensors file")
    elif damage == "wrong_weights":
        _fresh_policy(hidden_size=8).save_pretrained(tmp_path / "other")
        (path / "model.safetensors").write_bytes((tmp_path / "other" / "model.safetensors").read_bytes())
    elif damage == "corrupt_config":
        (path / "config.json").write_text("{not json")
    config = None if damage != "corrupt_config" else _config()
    with pytest.raises(PolicyError, match=match) as err:
        PnpLstmPolicy.from_pretrained(path, config=config)
    assert "\n" not in str(err.value)


def test_loading_a_checkpoint_for_other_features_names_the_mismatch(tmp_path):
    """make_policy swaps in the env's output features; a different action size must fail clearly."""
    path = _save_checkpoint(_fresh_policy(), tmp_path / "ckpt")
    cfg = PnpLstmConfig.from_pretrained(path)
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (14,))}
    with pytest.raises(PolicyError, match=r"trained with action of shape \(8,\), but the env/dataset provides \(14,\)"):
        PnpLstmPolicy.from_pretrained(path, config=cfg)
    assert PnpLstmPolicy.from_pretrained(path, config=PnpLstmConfig.from_pretrained(path)) is not None
