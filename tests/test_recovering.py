"""Tests of ``pnp_lstm --policy.mode=recovering``: no clock, variable-length episodes, the learned switch."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import torch

torch.set_num_threads(1)

from lerobot.configs import FeatureType, PolicyFeature  # noqa: E402
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE  # noqa: E402

from lerobot_pnp.errors import ConfigError, DatasetError  # noqa: E402
from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy  # noqa: E402
from lerobot_pnp.policy.configuration_pnp_lstm import STILL_ARM_PHASES  # noqa: E402
from lerobot_pnp.policy.modeling_pnp_lstm import PHASE_KEY, SUBTASK_KEY  # noqa: E402
from lerobot_pnp.policy.recovering import lstm_trunk_params  # noqa: E402

ENV_DIM = 7  # the `full` task: object xyz + (sin 4 yaw, cos 4 yaw) + goal xy
LMAX = 24


def _policy(**kw) -> PnpLstmPolicy:
    length = kw.pop("max_episode_length", LMAX)
    cfg = PnpLstmConfig(mode="recovering", hidden_size=kw.pop("hidden_size", 16), max_episode_length=length, **kw)
    cfg.input_features = {
        OBS_STATE: PolicyFeature(FeatureType.STATE, (8,)),
        OBS_ENV_STATE: PolicyFeature(FeatureType.ENV, (ENV_DIM,)),
    }
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (8,))}
    torch.manual_seed(0)
    policy = PnpLstmPolicy(cfg)
    policy.eval()
    return policy


def _episodes(lengths: list[int], seed: int = 0) -> tuple[dict[str, torch.Tensor], torch.Tensor]:
    """Episodes padded at the end to the longest; padding holds garbage that must not matter."""
    g = torch.Generator().manual_seed(seed)
    n, t = len(lengths), max(lengths)
    pad = torch.arange(t)[None, :] >= torch.tensor(lengths)[:, None]
    batch = {
        OBS_STATE: torch.randn(n, t, 8, generator=g),
        OBS_ENV_STATE: torch.randn(n, t, ENV_DIM, generator=g),
        ACTION: torch.randn(n, t, 8, generator=g),
        SUBTASK_KEY: (torch.arange(t)[None, :] >= 5).long().expand(n, t).clone(),
        PHASE_KEY: (torch.arange(t)[None, :] % 10).long().expand(n, t).clone(),
        f"{ACTION}_is_pad": pad,
    }
    return batch, pad


def test_config():
    with pytest.raises(ConfigError, match="mode"):
        PnpLstmConfig(mode="clockwork")
    cfg = PnpLstmConfig(mode="recovering", max_episode_length=41)
    assert cfg.observation_delta_indices == list(range(-40, 41))  # any frame's window holds its whole episode
    assert cfg.drop_n_last_frames == 0  # variable lengths: every frame is sampled
    clocked = PnpLstmConfig()
    assert clocked.mode == "clocked" and clocked.drop_n_last_frames == 9  # the paper's default is untouched
    assert clocked.observation_delta_indices == list(range(-9, 10))


def test_padding_is_masked_out_of_the_loss():
    policy = _policy()
    batch, pad = _episodes([10, 14, 19])
    loss, info = policy.forward(batch)
    garbage = {k: (v.masked_fill(pad[..., None], 1e3) if v.ndim == 3 else v) for k, v in batch.items()}
    loss2, _ = policy.forward(garbage)
    torch.testing.assert_close(loss, loss2)
    assert {"mse_action", "ce_subtask", "acc_subtask", "ce_phase", "acc_phase"} <= info.keys()
    # The same episode alone gives its own loss; the mean weights episodes by their real frames.
    per_sample, _ = policy.forward(batch, reduction="none")
    alone, _ = policy.forward({k: v[1:2, :14] for k, v in batch.items()})
    torch.testing.assert_close(per_sample[1], alone)
    torch.testing.assert_close(loss, (per_sample * torch.tensor([10.0, 14, 19])).sum() / 43)


@pytest.mark.parametrize("recurrent", [True, False])
def test_trunk_skips_the_frames_after_the_loss_without_changing_it(recurrent):
    """The loss runs the trunk only up to each episode's last frame in the loss (the LSTM in groups of similar
    length, the MLP on those frames): the same loss and gradients as one call over the padded batch."""
    from lerobot_pnp.policy.recovering import recovering_loss

    policy = _policy(num_layers=2, recurrent=recurrent)
    policy.train()
    net = policy.model
    lengths = [10, 10, 11, 12, 14, 17, 19, 23, 24, 3, 10, 21]  # groups worth running apart
    batch, pad = _episodes(lengths, seed=3)
    x = torch.cat([batch[OBS_STATE], batch[OBS_ENV_STATE]], dim=-1)
    valid = ~pad
    valid[4, 12:] = False  # a late episode's tail out of the loss: the trunk stops at frame 12 there
    valid[5, 2] = False  # a frame inside the loss window that is out of the loss still feeds the LSTM
    labels = (batch[SUBTASK_KEY], batch[PHASE_KEY])
    cfg = net.config
    params = list(net.parameters())
    padded = recovering_loss(net(x), batch[ACTION], valid, *labels, cfg.subtask_loss_weight, cfg.phase_loss_weight)
    grouped = net.loss(x, batch[ACTION], valid, *labels)
    torch.testing.assert_close(grouped[0], padded[0])
    for a, b in zip(torch.autograd.grad(grouped[0], params), torch.autograd.grad(padded[0], params), strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-6)
    # the skipped frames really are skipped: garbage there changes nothing
    x2 = x.clone()
    x2[4, 12:] = 1e3
    torch.testing.assert_close(net.loss(x2, batch[ACTION], valid, *labels)[0], grouped[0])


def test_labels_are_used_only_when_per_frame():
    policy = _policy()
    batch, _ = _episodes([12, 12])
    with_labels, _ = policy.forward(batch)
    # lerobot-train batches carry one label per sample (phase.* are not windowed): action loss only.
    batch[SUBTASK_KEY], batch[PHASE_KEY] = batch[SUBTASK_KEY][:, 0], batch[PHASE_KEY][:, 0]
    without, info = policy.forward(batch)
    assert "ce_subtask" not in info and float(without.detach()) < float(with_labels.detach())


def test_lerobot_window_equals_the_episode():
    """A stock lerobot-train window (-(L-1)..L-1 around any frame, `_is_pad` outside the episode)."""
    policy = _policy()
    batch, _ = _episodes([13])
    ep = {k: batch[k] for k in (OBS_STATE, OBS_ENV_STATE, ACTION)}
    ref, _ = policy.forward(ep)
    length = 2 * LMAX - 1
    for sampled in (0, 6, 12):
        start = LMAX - 1 - sampled
        pad = torch.ones(1, length, dtype=torch.bool)
        pad[:, start : start + 13] = False
        win = {f"{k}_is_pad": pad for k in ep}
        for k, v in ep.items():
            w = torch.full((1, length, v.shape[-1]), -7.0)
            w[:, start : start + 13] = v
            win[k] = w
        loss, _ = policy.forward(win)
        torch.testing.assert_close(loss, ref)


def test_select_action_carries_state_without_a_clock():
    """Step-by-step inference equals the teacher-forced sequence for 30 steps: no reset at step 5, no hold
    after step 10, and the state depends on the whole history."""
    policy = _policy()
    batch, _ = _episodes([30, 30])
    seq = policy.predict_sequence(batch)
    policy.reset()
    steps = torch.stack(
        [
            policy.select_action({OBS_STATE: batch[OBS_STATE][:, k], OBS_ENV_STATE: batch[OBS_ENV_STATE][:, k]})
            for k in range(30)
        ],
        dim=1,
    )
    torch.testing.assert_close(steps, seq, rtol=1e-5, atol=1e-5)
    assert not torch.allclose(steps[:, 12], steps[:, 11])  # still acting after the paper's 10 steps
    assert policy.last_subtask_prob.shape == (2,)
    # History matters: changing frame 2 changes the action at frame 20.
    other = {k: v.clone() for k, v in batch.items()}
    other[OBS_ENV_STATE][:, 2] += 1.0
    assert not torch.allclose(policy.predict_sequence(other)[:, 20], seq[:, 20])
    torch.testing.assert_close(policy.predict_sequence(other)[:, :2], seq[:, :2])  # causal


def test_two_layer_trunk_steps_as_it_trains():
    """``num_layers=2`` stacks a second LSTM layer (it used to be ignored in recovering mode): step-by-step
    inference equals the teacher-forced sequence, and the network differs from the one-layer one."""
    policy = _policy(num_layers=2, dropout=0.1)
    assert policy.model.lstm.num_layers == 2
    batch, _ = _episodes([20, 20])
    seq = policy.predict_sequence(batch)
    policy.reset()
    obs = [{OBS_STATE: batch[OBS_STATE][:, k], OBS_ENV_STATE: batch[OBS_ENV_STATE][:, k]} for k in range(20)]
    steps = torch.stack([policy.select_action(o) for o in obs], dim=1)
    torch.testing.assert_close(steps, seq, rtol=1e-5, atol=1e-5)
    assert policy.model.trunk_parameters() > _policy().model.trunk_parameters()
    with pytest.raises(ConfigError, match="shared_network and carry_hidden_across_subtasks are the clocked"):
        PnpLstmConfig(mode="recovering", shared_network=True)


@pytest.mark.parametrize("layers", [1, 2])
def test_memoryless_control_uses_a_matched_budget_and_no_history(layers):
    """The MLP control is matched to the trunk it replaces, a stacked one included (the recipe's is two layers)."""
    lstm = _policy(hidden_size=128, num_layers=layers)
    mlp = _policy(hidden_size=128, recurrent=False, num_layers=layers)
    d = 8 + ENV_DIM
    assert lstm.model.trunk_parameters() == lstm_trunk_params(d, 128, layers)
    assert (
        abs(mlp.model.trunk_parameters() - lstm_trunk_params(d, 128, layers)) / lstm_trunk_params(d, 128, layers) < 0.02
    )
    batch, _ = _episodes([20])
    other = {k: v.clone() for k, v in batch.items()}
    other[OBS_ENV_STATE][:, 2] += 1.0
    a, b = mlp.predict_sequence(batch), mlp.predict_sequence(other)
    torch.testing.assert_close(a[:, 3:], b[:, 3:])  # only frame 2's own output changes
    assert not torch.allclose(a[:, 2], b[:, 2])


def test_learns_a_switch_that_depends_on_what_it_observed():
    """The subtask is 'has the gripper ever closed' (a flag seen once, then gone): only memory can tell."""
    g = torch.Generator().manual_seed(1)
    n, t = 64, 16
    close_at = torch.randint(2, 12, (n,), generator=g)
    state = torch.randn(n, t, 8, generator=g) * 0.1
    state[torch.arange(n), close_at, 7] = 3.0  # the event, visible at one frame only
    subtask = (torch.arange(t)[None, :] > close_at[:, None]).long()
    action = torch.where(subtask[..., None].bool(), 1.0, -1.0).expand(n, t, 8).clone()
    batch = {
        OBS_STATE: state,
        OBS_ENV_STATE: torch.zeros(n, t, ENV_DIM),
        ACTION: action,
        SUBTASK_KEY: subtask,
        PHASE_KEY: subtask * 5,
    }
    results = {}
    for recurrent in (True, False):
        policy = _policy(hidden_size=32, recurrent=recurrent)
        policy.train()
        opt = torch.optim.Adam(policy.parameters(), lr=1e-2)
        for _ in range(150):
            loss, info = policy.forward(batch)
            opt.zero_grad()
            loss.backward()
            opt.step()
        results[recurrent] = info
    assert results[True]["acc_subtask"] > 0.97 and results[True]["mse_action"] < 0.05
    assert results[False]["acc_subtask"] < 0.9  # a memoryless net cannot know the flag was seen


def test_policy_construction_checks_episode_lengths():
    from types import SimpleNamespace

    cfg = PnpLstmConfig(mode="recovering", max_episode_length=20, hidden_size=8)
    cfg.input_features = {
        OBS_STATE: PolicyFeature(FeatureType.STATE, (8,)),
        OBS_ENV_STATE: PolicyFeature(FeatureType.ENV, (3,)),
    }
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (8,))}
    PnpLstmPolicy(cfg, dataset_meta=SimpleNamespace(episodes={"length": [10, 14, 20]}, fps=1))
    with pytest.raises(DatasetError, match="max_episode_length=20"):
        PnpLstmPolicy(cfg, dataset_meta=SimpleNamespace(episodes={"length": [10, 27]}, fps=1))


def test_latency_augmentation_delays_whole_episodes_by_one_step():
    from lerobot_pnp.policy.modeling_pnp_lstm import delay_some_episodes

    x = torch.arange(2 * 5 * 3, dtype=torch.float32).view(2, 5, 3)
    valid = torch.tensor([[True] * 5, [True, True, True, False, False]])
    same, same_valid = delay_some_episodes(x, valid, 0.0)
    torch.testing.assert_close(same, x)
    assert torch.equal(same_valid, valid)
    late, late_valid = delay_some_episodes(x, valid, 1.0)
    torch.testing.assert_close(late[:, 0], x[:, 0])  # frame 0 sees its own observation (the env's latency)
    torch.testing.assert_close(late[:, 1:], x[:, :-1])  # frame t sees frame t-1
    # the last real frame (the never-executed hold after success) leaves the loss, nothing else does
    assert late_valid.tolist() == [[True] * 4 + [False], [True, True, False, False, False]]
    # with phase labels, the first frame of a recovery (the phase goes back) leaves the loss too
    phase = torch.tensor([[0, 1, 2, 0, 1], [0, 1, 2, 3, 4]])
    _, told = delay_some_episodes(x, valid, 1.0, phase)
    assert told.tolist() == [[True, True, True, False, False], [True, True, False, False, False]]
    torch.manual_seed(0)
    mixed, _ = delay_some_episodes(torch.arange(400.0).view(200, 2, 1), torch.ones(200, 2, dtype=torch.bool), 0.5)
    n_late = int((mixed[:, 1] == mixed[:, 0]).sum())
    assert 70 < n_late < 130  # about half of the episodes, each either all late or all current
    # Training only: the augmented loss differs from the plain one, evaluation is untouched.
    with pytest.raises(ConfigError, match="latency_augment_prob"):
        PnpLstmConfig(mode="recovering", latency_augment_prob=1.5)
    policy = _policy(latency_augment_prob=1.0)
    batch, _ = _episodes([12, 12])
    plain, _ = policy.forward(batch)  # eval mode
    policy.train()
    delayed, _ = policy.forward(batch)
    assert float(delayed.detach()) != float(plain.detach())


@pytest.fixture(scope="module")
def full_root(tmp_path_factory):
    """A few `full` keyframe demonstrations (recoveries included, so the lengths differ)."""
    from lerobot_pnp.dataset import GenerateConfig, generate
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    root = tmp_path_factory.mktemp("full") / "data"
    env = BaxterPnPEnvConfig(preset="full", drop_prob=0.5)
    generate(
        GenerateConfig(
            repo_id="local/t_full", root=str(root), num_episodes=6, seed=3, workers=1, env=env, progress=False
        )
    )
    return root


def test_shipped_config_streams_whole_episodes(full_root):
    """configs/train_pnp_lstm_full.json trains from LeRobot's streaming dataset (as lerobot-train builds it:
    the policy's delta timestamps, ``max_num_shards=num_workers``): one pass yields every frame once, and each
    sample's window is its whole episode, so its loss equals the whole episode's (the fast path's batch)."""
    import json
    from pathlib import Path

    from lerobot.datasets import resolve_delta_timestamps
    from lerobot.datasets.lerobot_dataset import LeRobotDataset
    from lerobot.datasets.streaming_dataset import StreamingLeRobotDataset

    from lerobot_pnp.train_fast import policy_config_from_dict

    shipped = json.loads((Path(__file__).resolve().parents[1] / "configs" / "train_pnp_lstm_full.json").read_text())
    assert shipped["dataset"]["streaming"] is True and shipped["num_workers"] >= 1
    plain = LeRobotDataset("local/t_full", root=full_root)
    lengths = [int(n) for n in plain.meta.episodes["length"]]
    assert len(set(lengths)) > 1 and max(lengths) <= shipped["policy"]["max_episode_length"]
    cfg = policy_config_from_dict({**shipped["policy"], "hidden_size": 8})
    policy = _policy(hidden_size=8, max_episode_length=cfg.max_episode_length)
    delta = resolve_delta_timestamps(cfg, plain.meta)
    stream = StreamingLeRobotDataset(
        "local/t_full", root=full_root, delta_timestamps=delta, max_num_shards=shipped["num_workers"]
    )
    starts = [int(i) for i in plain.meta.episodes["dataset_from_index"]]
    seen = []
    for item in stream:
        ep = int(item["episode_index"])
        seen.append(int(item["index"]))
        whole = {k: torch.stack(list(plain.hf_dataset[k][starts[ep] : starts[ep] + lengths[ep]]))[None] for k in delta}
        window = {k: v[None] for k, v in item.items() if k in delta or k.endswith("_is_pad")}
        assert int((~window[f"{ACTION}_is_pad"]).sum()) == lengths[ep]
        torch.testing.assert_close(policy.forward(window)[0], policy.forward(whole)[0])
    assert sorted(seen) == list(range(sum(lengths)))


def test_late_observer_retimes_a_recovery_and_draws_lags_as_the_env_does():
    from lerobot_pnp.policy.latency import late_observer

    x = torch.arange(8.0).view(1, 8, 1)
    valid = torch.ones(1, 8, dtype=torch.bool)
    phase = torch.tensor([[0, 1, 2, 3, 1, 2, 3, 4]])  # a recovery starts at frame 4 (the phase goes back)
    seen, kept, src = late_observer(x, valid, 1.0, phase, stretch=True)
    # the late robot commands one more step of its old plan (a copy of frame 4, out of the loss), then the
    # expert's recovery from its first action: the frame trained on action 4 sees frame 4 (the event) at last
    assert src.tolist() == [[0, 1, 2, 3, 4, 4, 5, 6, 7]]
    assert seen.squeeze(-1).tolist() == [[0, 0, 1, 2, 3, 4, 4, 5, 6]]
    assert kept.tolist() == [[True] * 4 + [False] + [True] * 3 + [False]]
    # lags drawn in 1..max per late episode, redrawn in 0..max with the jitter: never beyond max, never early
    torch.manual_seed(0)
    x = torch.arange(40.0).view(1, 40, 1).expand(300, 40, 1)
    seen, _, src = late_observer(x, torch.ones(300, 40, dtype=torch.bool), 1.0, None, 2, 0.5)
    lag = torch.arange(40) - seen.squeeze(-1)
    assert torch.equal(src, torch.arange(40).expand(300, 40))  # no phase labels: nothing retimed
    assert set(lag[:, 2:].unique().tolist()) == {0, 1, 2}
    assert set(lag[:, 1].unique().tolist()) <= {0, 1}  # frame 0 shows itself, as the env's first observation
    with pytest.raises(ConfigError, match="latency_augment_max"):
        PnpLstmConfig(mode="recovering", latency_augment_max=0)
    policy = _policy(latency_augment_prob=1.0, latency_augment_stretch=True, latency_augment_jitter=0.5)
    policy.train()
    loss, _ = policy.forward(_episodes([12, 20])[0])
    assert torch.isfinite(loss)


def _run_plant(policy: PnpLstmPolicy, latencies: list[int], steps: int) -> list:
    """A synthetic plant for two envs: each step the robot reaches the pose the command leads to (a deterministic
    function of the command that spreads nearby commands apart, so the plan never settles); observations are
    ``latencies[t]`` steps old (per step: jitter). Returns the commands issued."""
    env_obs = torch.zeros(2, ENV_DIM)
    history = [torch.randn(2, 8, generator=torch.Generator().manual_seed(1))]  # the state after each step
    commands, obs = [], history[0]
    policy.reset()
    for t in range(steps):
        action = policy.select_action({OBS_STATE: obs, OBS_ENV_STATE: env_obs})
        commands.append(action)
        history.append(2.0 * torch.sin(50.0 * action))
        obs = history[max(0, len(history) - 1 - latencies[t])]
    return commands


def _decisions(commands: list) -> list:
    """The distinct commands in order (a held command repeats)."""
    out = [commands[0]]
    for c in commands[1:]:
        if not torch.equal(c, out[-1]):
            out.append(c)
    return out


def test_observation_gate_makes_the_plan_independent_of_latency():
    """With ``await_observation`` the planner steps only on observations that show its last move, so the
    sequence of commands it plans is the same at latency 0, 2 (beyond any training) and under jitter; at latency 2
    each is held until its move is seen (three steps). Without the gate the plan changes with the latency."""
    gated = _policy(await_observation=True, await_state_tol=0.05, await_action_tol=0.01)
    at0 = _decisions(_run_plant(gated, [0] * 12, 12))
    late = _run_plant(gated, [2] * 36, 36)
    assert len(at0) == 12  # latency 0: a new command every step, as without the gate
    assert all(torch.equal(late[3 * k], late[3 * k + 2]) for k in range(12))  # each held for its 3 steps
    for a, b in zip(at0, _decisions(late), strict=True):
        torch.testing.assert_close(a, b)
    g = torch.Generator().manual_seed(3)
    jitter = torch.randint(0, 3, (60,), generator=g).tolist()
    for a, b in zip(at0, _decisions(_run_plant(gated, jitter, 60))[:12], strict=True):
        torch.testing.assert_close(a, b)
    plain = _policy()
    assert not torch.allclose(_run_plant(plain, [0] * 6, 6)[5], _run_plant(plain, [2] * 6, 6)[5])


def test_observation_gate_lets_the_planner_run_ahead_by_its_trained_latency():
    """``await_in_flight=1`` (a planner trained on observations up to one step late, the default for it): at
    latency 1 it never waits and acts exactly as without the gate; at latency 2 it waits one step per move, so
    it sees the observations it would see at latency 1, and plans the same commands."""
    plain = _policy(latency_augment_prob=0.5)
    gated = _policy(latency_augment_prob=0.5, await_observation=True, await_state_tol=0.05, await_action_tol=0.01)
    assert gated.config.in_flight_moves == 1 and _policy().config.in_flight_moves == 0
    at1 = _run_plant(plain, [1] * 12, 12)
    for a, b in zip(at1, _run_plant(gated, [1] * 12, 12), strict=True):
        torch.testing.assert_close(a, b)
    late = _decisions(_run_plant(gated, [2] * 24, 24))
    for a, b in zip(at1, late[:12], strict=True):
        torch.testing.assert_close(a, b)


def test_observation_gate_gives_up_on_a_move_it_cannot_see():
    """A command whose move never shows in the robot state (the plant ignores it; only the object observation
    changes) is held ``await_max_steps`` steps, then the planner steps on what it sees."""
    policy = _policy(await_observation=True, await_state_tol=0.05, await_action_tol=0.01, await_max_steps=3)
    g = torch.Generator().manual_seed(0)
    policy.reset()
    actions = [
        policy.select_action({OBS_STATE: torch.zeros(2, 8), OBS_ENV_STATE: 3 * torch.randn(2, ENV_DIM, generator=g)})
        for _ in range(9)
    ]
    changes = [k for k in range(1, 9) if not torch.equal(actions[k], actions[k - 1])]
    assert changes == [4, 8]  # decided at 0, held 3 steps, decided at 4, ...


@pytest.mark.parametrize(
    "field, value",
    [("await_state_tol", 0.0), ("await_action_tol", -1.0), ("await_max_steps", 0), ("await_in_flight", -1)],
)
def test_observation_gate_settings_are_checked(field, value):
    with pytest.raises(ConfigError, match=field):
        PnpLstmConfig(mode="recovering", **{field: value})


def _force_phase(policy: PnpLstmPolicy, phase: int) -> None:
    """Make the phase classifier predict ``phase`` whatever it sees."""
    head = policy.model.phase_head
    with torch.no_grad():
        head.weight.zero_()
        head.bias.copy_(torch.nn.functional.one_hot(torch.tensor(phase), head.bias.numel()).float())


@pytest.mark.parametrize("phase, still", [(2, True), (4, True), (7, True), (9, True), (1, False), (6, False)])
def test_still_arm_phases_keep_the_arm_where_the_phase_says_the_fsm_does(phase, still):
    """``still_arm_phases``: on a keyframe the phase classifier labels with one of them (a close, a hold, an
    open), the arm command is the last one and only the gripper comes from the network; other keyframes are the
    network's."""
    policy = _policy(still_arm_phases=list(STILL_ARM_PHASES))
    plain = _policy()
    _force_phase(policy, phase)
    _force_phase(plain, phase)
    g = torch.Generator().manual_seed(1)
    obs = [
        {OBS_STATE: torch.randn(2, 8, generator=g), OBS_ENV_STATE: torch.randn(2, ENV_DIM, generator=g)}
        for _ in range(5)
    ]
    policy.reset()
    plain.reset()
    got = [policy.select_action(o) for o in obs]
    net = [plain.select_action(o) for o in obs]
    torch.testing.assert_close(got[0], net[0])  # nothing commanded before the first keyframe
    for k in range(1, 5):
        torch.testing.assert_close(got[k][:, -1], net[k][:, -1])  # the gripper is always the network's
        arm = got[k - 1][:, :-1] if still else net[k][:, :-1]
        torch.testing.assert_close(got[k][:, :-1], arm)
    assert not torch.allclose(net[1][:, :-1], net[0][:, :-1])  # the network itself would have moved the arm


def test_still_arm_tol_holds_only_the_large_arm_moves():
    """``still_arm_tol``: on a still-labelled keyframe, an env whose network would move the arm by more than the
    tolerance (normalised) keeps its last arm command; an env whose network moves it less keeps the network's
    keyframe (a refinement of the pose); the gripper is the network's in both."""
    plain = _policy()
    _force_phase(plain, 7)
    g = torch.Generator().manual_seed(3)
    x0, x1 = torch.randn(2, 8 + ENV_DIM, generator=g), torch.randn(2, 8 + ENV_DIM, generator=g)
    with torch.no_grad():
        first, state = plain.model.act(x0, None)
        net, _ = plain.model.act(x1, state)
    move = (net[:, :-1] - first[:, :-1]).norm(dim=-1)
    assert float((move[0] - move[1]).abs()) > 1e-3  # the two envs' moves differ: a tolerance between them splits
    tol = float(move.mean())
    policy = _policy(still_arm_phases=[7], still_arm_tol=tol)
    _force_phase(policy, 7)
    with torch.no_grad():
        _, state = policy.model.act(x0, None)
        got, _ = policy.model.act(x1, state)
    held = move > tol
    torch.testing.assert_close(got[:, -1], net[:, -1])
    torch.testing.assert_close(got[held, :-1], first[held, :-1])
    torch.testing.assert_close(got[~held, :-1], net[~held, :-1])
    with pytest.raises(ConfigError, match="still_arm_tol must be >= 0"):
        PnpLstmConfig(mode="recovering", still_arm_tol=-0.1)


def test_still_arm_phases_are_the_demonstrations_still_keyframes(full_root):
    """The valid ``still_arm_phases`` are exactly the phases whose demonstrated keyframe repeats the last arm
    command (the expert's FSM); every other phase moves the arm, and is refused."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset("local/t_full", root=full_root).hf_dataset
    action = torch.stack(list(ds["action"]))
    phase = torch.tensor([int(p) for p in ds["phase.index"]])
    episode = torch.tensor([int(e) for e in ds["episode_index"]])
    same = episode[1:] == episode[:-1]
    still = (action[1:, :-1] - action[:-1, :-1]).abs().amax(dim=-1) < 1e-6
    for p in range(10):
        at = same & (phase[1:] == p)
        if p in STILL_ARM_PHASES:
            assert bool(at.any()) and bool(still[at].all()), p
        elif bool(at.any()):
            assert not bool(still[at].any()), p
    with pytest.raises(ConfigError, match=r"still_arm_phases must be among .*\[2, 4, 7, 9\], got \[3\]"):
        PnpLstmConfig(mode="recovering", still_arm_phases=[3])


@pytest.mark.parametrize(
    "name", ["dagger", "dagger_curve_full", "dagger_curve_paper", "dart_full", "dart_paper", "train_pnp_lstm_full"]
)
def test_shipped_configs_train_the_recovering_recipe(name):
    """The configs that say they train the recovering planner hold every field of the recipe the study trains."""
    from lerobot_pnp.policy.recipes import RECOVERING_RECIPE

    policy = json.loads((Path(__file__).parents[1] / "configs" / f"{name}.json").read_text())["policy"]
    assert {k: policy.get(k) for k in RECOVERING_RECIPE} == RECOVERING_RECIPE


def test_shipped_recovering_configs_hold_the_longest_episode_of_the_full_task():
    """Every shipped config that trains a recovering planner (pnp_lstm or pnp_pixels) gives its training windows the
    longest episode the ``full`` task allows: its keyframe budget + the final state (the rule the study applies,
    ``report.recipes.policy_settings``); a shorter window refuses the longest demonstrations."""
    from lerobot_pnp.presets import FULL_TASK

    configs = sorted((Path(__file__).parents[1] / "configs").glob("*.json"))
    recovering = {p.name: json.loads(p.read_text()).get("policy", {}) for p in configs}
    recovering = {name: p for name, p in recovering.items() if p.get("mode") == "recovering"}
    assert {"train_pnp_lstm_full.json", "train_pnp_pixels.json", "dagger.json"} <= set(recovering)
    wrong = {n: p.get("max_episode_length") for n, p in recovering.items()
             if p.get("max_episode_length") != FULL_TASK["keyframe_budget"] + 1}  # fmt: skip
    assert not wrong, f"max_episode_length must be {FULL_TASK['keyframe_budget'] + 1}: {wrong}"


def test_memory_per_attempt_trains_each_attempt_from_a_zero_state():
    """With ``memory_per_attempt`` an episode whose labels go back from place to pick trains as its attempts would
    alone, each from its own first frame; the frame where the labels go back is also the last of the attempt it
    ends (where inference recognises the switch). Without labels it says how to get them."""
    policy = _policy(memory_per_attempt=True)
    batch, _ = _episodes([16])
    batch[SUBTASK_KEY][0] = torch.tensor([0] * 4 + [1] * 5 + [0] * 3 + [1] * 4)  # back to pick at frame 9
    per_episode, _ = policy.forward(batch, reduction="none")
    pieces = [({k: v[:, a:b] for k, v in batch.items()}, b - a) for a, b in ((0, 10), (9, 16))]
    plain = _policy()  # the same weights, memory carried: each piece alone
    alone = [plain.forward(piece)[0] * n for piece, n in pieces]
    torch.testing.assert_close(per_episode[0], sum(alone) / 17)
    carried, _ = plain.forward(batch, reduction="none")
    assert not torch.allclose(carried, per_episode)  # the memory across the cut mattered before
    # The teacher-forced sequence restarts at the same frame; the first attempt is untouched.
    seq = policy.predict_sequence(batch)
    torch.testing.assert_close(seq[:, 9:], policy.predict_sequence({k: v[:, 9:] for k, v in batch.items()}))
    torch.testing.assert_close(seq[:, :9], _policy().predict_sequence(batch)[:, :9])
    no_labels = {k: v for k, v in batch.items() if k != SUBTASK_KEY}
    with pytest.raises(DatasetError, match="memory_per_attempt .* carries none"):
        policy.forward(no_labels)
    with pytest.raises(ConfigError, match="memory_per_attempt is the recovering planner's"):
        PnpLstmConfig(memory_per_attempt=True)


@pytest.mark.parametrize("per_attempt", [True, False])
def test_memory_per_attempt_restarts_where_the_switch_goes_back_to_pick(per_attempt):
    """At inference the step where the subtask classifier goes from place back to pick is re-run from the zero
    state: its action and the memory it leaves are those of a fresh episode starting on that observation."""
    policy = _policy(memory_per_attempt=per_attempt)
    with torch.no_grad():  # the classifier says pick, whatever the state
        policy.model.subtask_head.weight.zero_()
        policy.model.subtask_head.bias.copy_(torch.tensor([5.0, -5.0]))
    batch, _ = _episodes([6])
    obs = [{OBS_STATE: batch[OBS_STATE][:, k], OBS_ENV_STATE: batch[OBS_ENV_STATE][:, k]} for k in range(6)]
    policy.reset()
    for o in obs[:3]:
        policy.select_action(o)
    policy._state = dataclasses.replace(policy._state, subtask_prob=torch.ones(1))  # the last step said place
    after = torch.stack([policy.select_action(o) for o in obs[3:]])
    policy.reset()
    fresh = torch.stack([policy.select_action(o) for o in obs[3:]])
    if per_attempt:
        torch.testing.assert_close(after, fresh)
    else:
        assert not torch.allclose(after[0], fresh[0]) and not torch.allclose(after[1], fresh[1])


def test_attempts_start_where_a_late_robot_can_see_the_event():
    """Frames out of the loss (a late observer's blind frames, a retimed recovery's copies) stay with the attempt
    the late robot is still running: the new attempt starts at the first frame in the loss that says pick, which is
    also the last of the attempt it ends."""
    from lerobot_pnp.policy.recovering import Attempts

    subtask = torch.tensor([[0, 0, 1, 1, 0, 0, 0, 1], [0, 1, 1, 0, 0, 1, 1, 1]])
    valid = torch.ones(2, 8, dtype=torch.bool)
    valid[0, 4] = False  # the first pick frame is blind: the cut waits for frame 5
    valid[1, 6:] = False  # no cut after the last frame in the loss
    attempts = Attempts(subtask, valid)
    frames = torch.arange(16.0).view(2, 8, 1)
    rows = attempts.split(frames).squeeze(-1)
    assert rows[:, 0].tolist() == [0.0, 5.0, 8.0, 11.0]  # each attempt's first frame
    assert rows[0, :6].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]  # ... the first ends on the next one's first
    assert attempts.split(valid)[0].sum() == 5  # its blind frame stays out of the loss
    torch.testing.assert_close(attempts.merge(attempts.split(frames)), frames)
