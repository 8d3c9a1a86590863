"""What the ``pnp_lstm`` policy keeps from before: its numbers and the checkpoints written by older code.

Golden tensors: the loss (training mode: latency augmentation, input noise, dropout), its gradients and
``select_action`` of both planners (a gated run included), frozen from the code before the planners became two
classes, so that a refactor that claims "behaviour unchanged" is held to the bit.
``tests/golden/pnp_lstm.pt`` was written by ``python tests/test_policy_compat.py --write`` (do it again only
for a change that is *meant* to change the numbers, and say so). On the machine kind that wrote it (same torch,
same CPU capability and model) the comparison is ``torch.equal``; elsewhere float kernels may round differently,
so it is a tight ``assert_close`` there, with each closed loop replayed on the frozen run's observations. The file
in the repository predates the CPU model in the machine kind (an AMD EPYC wrote it; an Intel Xeon with the same
capability differs in the last bit), so it is compared the second way on every machine.
Rewritten once on purpose: when the recovering trunk stopped running on the padding after each episode's last
frame, its random draws (dropout masks) cover fewer frames, so the recurrent planners' training-mode numbers
(loss, gradients, info) changed; every ``select_action`` output matched the old file.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import torch

torch.set_num_threads(1)

from lerobot.configs import FeatureType, PolicyFeature, PreTrainedConfig  # noqa: E402
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE  # noqa: E402

from lerobot_pnp.policy import PnpLstmConfig, PnpLstmPolicy, make_pnp_lstm_pre_post_processors  # noqa: E402

GOLDEN = Path(__file__).resolve().parent / "golden" / "pnp_lstm.pt"
ENV_DIM = 7
AUGMENT = {"input_noise_std": 0.05, "latency_augment_prob": 0.5, "dropout": 0.1}
RECOVERING = {"mode": "recovering", "max_episode_length": 16}
CASES = {
    "clocked": {},
    "clocked_shared": {"shared_network": True, "carry_hidden_across_subtasks": True, "num_layers": 2},
    "clocked_memoryless": {"recurrent": False},
    "recovering": {
        **RECOVERING,
        "latency_augment_max": 2,
        "latency_augment_jitter": 0.5,
        "latency_augment_stretch": True,
    },
    "recovering_mlp": {**RECOVERING, "recurrent": False},
    "recovering_gated": {**RECOVERING, "await_observation": True, "await_state_tol": 0.05, "await_action_tol": 0.01},
}


def _policy(kw: dict) -> PnpLstmPolicy:
    cfg = PnpLstmConfig(hidden_size=16, **AUGMENT, **kw)
    cfg.input_features = {
        OBS_STATE: PolicyFeature(FeatureType.STATE, (8,)),
        OBS_ENV_STATE: PolicyFeature(FeatureType.ENV, (ENV_DIM,)),
    }
    cfg.output_features = {ACTION: PolicyFeature(FeatureType.ACTION, (8,))}
    torch.manual_seed(0)
    return PnpLstmPolicy(cfg)


def _batch(recovering: bool) -> dict[str, torch.Tensor]:
    """Clocked: a lerobot-train window (19 frames, the episode at 4..13); recovering: padded episodes with labels."""
    g = torch.Generator().manual_seed(7)
    n, t = 3, (16 if recovering else 19)
    batch = {
        OBS_STATE: torch.randn(n, t, 8, generator=g),
        OBS_ENV_STATE: torch.randn(n, t, ENV_DIM, generator=g),
        ACTION: torch.randn(n, t, 8, generator=g),
    }
    pos = torch.arange(t)[None, :]
    if recovering:
        lengths = torch.tensor([[10], [13], [16]])
        batch["phase.index"] = torch.tensor([0, 1, 2, 3, 4, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 9]).expand(n, t).clone()
        batch["phase.subtask"] = (batch["phase.index"] >= 5).long()
        batch[f"{ACTION}_is_pad"] = pos >= lengths
    else:
        pad = (pos < 4) | (pos >= 14)
        batch.update({f"{k}_is_pad": pad.expand(n, t).clone() for k in (OBS_STATE, OBS_ENV_STATE, ACTION)})
    return batch


def _plant(policy: PnpLstmPolicy, steps: int, latency: int, replay: torch.Tensor | None = None) -> torch.Tensor:
    """``select_action`` in closed loop with a synthetic plant (observations ``latency`` steps old).

    The plant (``2 sin(50 a)``) spreads nearby commands apart, so a last-bit difference in a float kernel grows
    step by step. ``replay``: the plant is driven by these frozen actions instead of the policy's own (the
    observations of the frozen run, each step from the frozen past), so that the policy's answers can be compared
    step by step on a machine that rounds differently; on the machine that froze them it is the closed loop."""
    g = torch.Generator().manual_seed(1)
    env_obs = torch.randn(2, ENV_DIM, generator=g)
    history = [torch.randn(2, 8, generator=g)]
    obs, actions = history[0], []
    policy.reset()
    for t in range(steps):
        action = policy.select_action({OBS_STATE: obs, OBS_ENV_STATE: env_obs})
        actions.append(action)
        history.append(2.0 * torch.sin(50.0 * (action if replay is None else replay[:, t])))
        obs = history[max(0, len(history) - 1 - latency)]
    return torch.stack(actions, dim=1)


def golden_outputs() -> dict[str, torch.Tensor]:
    """Every frozen tensor, named ``<case>/<what>``."""
    out: dict[str, torch.Tensor] = {}
    for name, kw in CASES.items():
        policy = _policy(kw)
        batch = _batch(policy.config.mode == "recovering")
        policy.train()
        torch.manual_seed(1)
        loss, info = policy.forward(batch)
        loss.backward()
        out[f"{name}/loss"] = loss.detach()
        out[f"{name}/grads"] = torch.stack([p.grad.sum() for p in policy.parameters()])  # one per weight tensor
        for key, value in sorted(info.items()):
            out[f"{name}/info/{key}"] = torch.tensor(value, dtype=torch.float64)
        torch.manual_seed(2)
        out[f"{name}/per_sample"] = policy.forward(batch, reduction="none")[0].detach()
        policy.eval()
        with torch.no_grad():
            out[f"{name}/sequence"] = policy.predict_sequence(batch)
        out[f"{name}/actions"] = _plant(policy, 14 if "clocked" in name else 20, 0)
        if name == "recovering_gated":
            out[f"{name}/actions_latency2"] = _plant(policy, 24, 2)
    return out


def _machine() -> str:
    """The kind of machine whose float kernels round alike: torch, the CPU capability and the CPU model (two CPUs
    with the same capability, an AMD EPYC and an Intel Xeon, were seen to differ in the last bit of a gradient)."""
    return f"torch {torch.__version__}, cpu {torch.backends.cpu.get_cpu_capability()}, {_cpu_model()}"


def _cpu_model() -> str:
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        import platform

        return platform.processor() or "unknown"
    return next((ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("model name")), "unknown")


def test_policy_matches_its_golden_tensors():
    stored = torch.load(GOLDEN, weights_only=True)
    frozen, machine = stored["tensors"], stored["machine"]
    now = golden_outputs()
    assert now.keys() == frozen.keys()
    gated = now["recovering_gated/actions_latency2"]
    assert torch.equal(gated[:, 2], gated[:, 1]) and not torch.equal(gated[:, 1], gated[:, 0])  # the gate held
    same_kind = machine == _machine()
    for key, value in now.items():
        if same_kind:
            assert torch.equal(value, frozen[key]), key
            continue
        # other float kernels: the same numbers up to rounding; a closed loop is replayed on the frozen run's
        # observations, since its plant grows a rounding difference into a different trajectory
        if "/actions" in key:
            name = key.split("/")[0]
            policy = _policy(CASES[name])
            policy.eval()
            value = _plant(policy, value.shape[1], 2 if key.endswith("latency2") else 0, replay=frozen[key])
        torch.testing.assert_close(value, frozen[key], rtol=1e-5, atol=1e-6, msg=key)


def test_checkpoints_with_the_retired_balance_window_loss_key_still_load(tmp_path):
    """``balance_window_loss`` did nothing; it is no constructor argument or option any more, but the config.json of
    older checkpoints carries it: every loader reads them (lerobot-eval's base-class path included)."""
    import draccus

    from lerobot_pnp.evaluation.checkpoints import load_policy

    policy = _policy(CASES["recovering_gated"])
    policy.save_pretrained(tmp_path)
    stats = {k: {"mean": torch.zeros(d), "std": torch.ones(d)} for k, d in ((OBS_STATE, 8), (OBS_ENV_STATE, 7))}
    for processor in make_pnp_lstm_pre_post_processors(policy.config, {**stats, ACTION: stats[OBS_STATE]}):
        processor.save_pretrained(tmp_path)
    config = json.loads((tmp_path / "config.json").read_text())
    config["balance_window_loss"] = False  # the key, with a value that did nothing either
    (tmp_path / "config.json").write_text(json.dumps(config))
    for cfg in (PreTrainedConfig.from_pretrained(tmp_path), PnpLstmConfig.from_pretrained(tmp_path)):
        assert isinstance(cfg, PnpLstmConfig) and cfg.await_observation and cfg.hidden_size == 16
    policy.eval()
    expected = _plant(policy, 6, 2)
    for loaded in (PnpLstmPolicy.from_pretrained(tmp_path), load_policy(tmp_path).policy):
        loaded.eval()
        assert torch.equal(_plant(loaded, 6, 2), expected)
        loaded.config.await_observation = False  # an inference-time override (heldout_protocol_eval.py) ...
        assert not torch.equal(_plant(loaded, 6, 2), expected)  # ... reaches the planner at the next reset
    with pytest.raises(TypeError, match="balance_window_loss"):
        PnpLstmConfig(balance_window_loss=False)
    with pytest.raises(SystemExit):  # argparse: unrecognized arguments
        draccus.parse(PnpLstmConfig, args=["--balance_window_loss=false"])


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        pytest.exit("usage: python tests/test_policy_golden.py --write")
    import lerobot_pnp  # noqa: F401  (registers the policy, as conftest does)

    GOLDEN.parent.mkdir(exist_ok=True)
    torch.save({"machine": _machine(), "tensors": golden_outputs()}, GOLDEN)
    print(f"wrote {GOLDEN}")
