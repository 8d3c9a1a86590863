"""Installing the plugin changes nothing for other LeRobot work, and our own runs see it whole.

LeRobot imports the plugin (the ``lerobot_policy_pnp_lstm`` shim) in every ``lerobot-*`` process. Plugin discovery
alone must leave the process as it was: no environment variable, no error hook, no simulator or modeling module
of ours; a ``lerobot-train`` of another robot's dataset writes the same checkpoint bytes with and without the
plugin. A run on our env, policy or data gets the plugin's checks: a dataset's invalid recorded task stops
``lerobot-train`` at start-up in one line, a checkpoint ``lerobot-eval`` cannot load on our env is one line, and
every reader of a recorded task refuses an unknown field the same way.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.recorded_files import RECORDED_FILE, write_recorded

BIN = Path(sys.executable).parent
PLAIN_ENV = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}  # as a user without our defaults
PLAIN_ENV.update({"OMP_NUM_THREADS": "1", "HF_HUB_OFFLINE": "1", "PYTHONPATH": os.pathsep.join(sys.path)})

# LeRobot's plugin discovery in a fresh process named like a stock script (its arguments: the script's argv), then
# what the process looks like (THEN: more steps, which add to ``seen``).
_DISCOVERY = r"""
import importlib.metadata as md, json, os, sys
sys.argv = sys.argv[1:]
hook_before = sys.excepthook
from lerobot.utils.import_utils import register_third_party_plugins
register_third_party_plugins()
seen = {"plugin": "lerobot_policy_pnp_lstm" in sys.modules, "MUJOCO_GL": os.environ.get("MUJOCO_GL"),
        "hook_unchanged": sys.excepthook is hook_before, "mujoco": "mujoco" in sys.modules,
        "lerobot_configs": "lerobot.configs" in sys.modules,
        "ours": sorted(m for m in sys.modules if m.startswith("lerobot_pnp"))}
THEN
print(json.dumps(seen))
"""


def _discovery(argv: list[str], then: str = "") -> dict:
    code = _DISCOVERY.replace("THEN", then)
    proc = subprocess.run(
        [sys.executable, "-c", code, *argv], env=PLAIN_ENV, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


LIGHT = {
    "lerobot_pnp",
    "lerobot_pnp.integration.registration",
    "lerobot_pnp.presets",
    "lerobot_pnp.integration.stock_cli",
}
LIGHT |= {"lerobot_pnp.sim.recorded_files", "lerobot_pnp.errors", "lerobot_pnp.version", "lerobot_pnp.sim.mujoco_gl"}
# the packages holding them, whose __init__ imports nothing
LIGHT |= {"lerobot_pnp.integration", "lerobot_pnp.sim"}

# After discovery, what lerobot-train / lerobot-eval do later in the calibrate order: LeRobot's config modules
# imported after the plugin, our configs parsed, the policy class asked for (its modeling loads then).
_THEN_PARSE = r"""
from dataclasses import dataclass
import draccus
from lerobot.configs.policies import PreTrainedConfig
from lerobot.envs.configs import EnvConfig

@dataclass
class Run:
    env: EnvConfig
    policy: PreTrainedConfig

run = draccus.parse(Run, args=["--env.type=baxter_pnp", "--env.keyframe_budget=12", "--policy.type=pnp_lstm"])
parsed = sorted(m for m in sys.modules if m.startswith("lerobot_pnp"))
from lerobot.policies.factory import get_policy_class
policy_class = get_policy_class("pnp_lstm")
from lerobot_pnp.policy.modeling_pnp_lstm import TaskRecord
seen.update(env=type(run.env).__name__, budget=run.env.keyframe_budget, policy=run.policy.type, parsed=parsed,
            policy_class=policy_class.__name__, task_record=TaskRecord.read is not None,
            MUJOCO_GL_after=os.environ.get("MUJOCO_GL"))
"""


def test_plugin_discovery_alone_changes_nothing_and_our_configs_still_parse():
    """A real-robot command (lerobot-calibrate): the plugin is imported and leaves no trace but a few plain
    modules (the gym id): no MUJOCO_GL, Python's excepthook, no MuJoCo, no LeRobot config module loaded on its
    behalf. LeRobot's configs imported afterwards still parse ``--env.type=baxter_pnp`` and
    ``--policy.type=pnp_lstm``; the policy's modeling loads only when LeRobot asks for the policy class."""
    seen = _discovery(["lerobot-calibrate", "--help"], then=_THEN_PARSE)
    assert seen["plugin"], seen
    assert seen["MUJOCO_GL"] is None and seen["hook_unchanged"] and not seen["mujoco"], seen
    assert set(seen["ours"]) <= LIGHT and not seen["lerobot_configs"], seen
    assert (seen["env"], seen["budget"], seen["policy"]) == ("BaxterPnPEnvConfig", 12, "pnp_lstm"), seen
    assert not any(m.startswith(("lerobot_pnp.policy.modeling", "lerobot_pnp.sim.physics")) for m in seen["parsed"])
    assert seen["policy_class"] == "PnpLstmPolicy" and seen["task_record"], seen
    assert seen["MUJOCO_GL_after"] is None, seen


@pytest.mark.parametrize(
    ("argv", "ours"),
    [
        (["lerobot-calibrate", "--robot.type=so100_follower"], False),
        (["lerobot-train", "--policy.type=act", "--dataset.repo_id=x/y", "--dataset.root=/none/x"], False),
        (["lerobot-train", "--policy.type", "pnp_lstm", "--dataset.root=/none/x"], True),
        (["lerobot-train", "--policy.type=pnp_pixels", "--dataset.root=/none/x"], True),
        (["lerobot-eval", "--env.type=baxter_pnp", "--policy.path=/none"], True),
        (["lerobot-train", "--policy.type=act", "--dataset.root=RECORDED"], True),
        (["lerobot-eval", "--env.type=aloha", "--policy.path=CHECKPOINT"], True),
    ],
)
def test_hooks_only_in_a_lerobot_run_on_our_env_policy_or_data(argv, ours, tmp_path, monkeypatch):
    from lerobot_pnp.integration.registration import install_stock_hooks

    write_recorded(BaxterPnPEnvConfig(), tmp_path / "data")
    (tmp_path / "ckpt").mkdir()
    (tmp_path / "ckpt/config.json").write_text(json.dumps({"type": "pnp_lstm"}))
    argv = [a.replace("RECORDED", str(tmp_path / "data")).replace("CHECKPOINT", str(tmp_path / "ckpt")) for a in argv]
    monkeypatch.setattr(sys, "argv", argv)
    monkeypatch.setattr(sys, "excepthook", sys.__excepthook__)  # restored after the test
    monkeypatch.delenv("LEROBOT_PNP_DEBUG", raising=False)
    install_stock_hooks()
    assert (sys.excepthook is not sys.__excepthook__) == ours


def test_mujoco_gl_default_only_on_linux_and_never_over_the_user(monkeypatch):
    from lerobot_pnp.sim.mujoco_gl import default_mujoco_gl

    monkeypatch.delitem(sys.modules, "mujoco", raising=False)
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    for platform, expected in (("darwin", None), ("win32", None), ("linux", "egl")):
        monkeypatch.setattr(sys, "platform", platform)
        default_mujoco_gl()
        assert os.environ.get("MUJOCO_GL") == expected
        monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    default_mujoco_gl()
    assert os.environ["MUJOCO_GL"] == "osmesa"


# ------------------------------------------------------------------------------------- recorded task: one rule
def test_an_unknown_field_in_a_recorded_task_is_refused_by_every_reader(tmp_path):
    """lerobot-eval's reader (the env config's task source), train's (the task a checkpoint records, and its
    copy), viz's (replay and rollouts): one message naming the field and the version that cannot read it."""
    import types

    from lerobot_pnp.integration.recorded_task import copy_recorded, dataset_task, read_recorded
    from lerobot_pnp.version import __version__
    from lerobot_pnp.viz.rollouts import rollout_config
    from lerobot_pnp.viz.sources import replay_config

    root = tmp_path / "data"
    write_recorded(BaxterPnPEnvConfig(), root)
    record = json.loads((root / RECORDED_FILE).read_text())
    (root / RECORDED_FILE).write_text(json.dumps({**record, "gripper_tilt": 0.1}))
    readers = {
        "eval": lambda: BaxterPnPEnvConfig.from_source(str(root)),
        "train": lambda: dataset_task(root),
        "train copy": lambda: copy_recorded(root, tmp_path),
        "viz replay": lambda: replay_config(types.SimpleNamespace(root=root, fps=1)),
        "viz rollout": lambda: rollout_config(str(tmp_path / "ckpt"), str(root), None),
        "read": lambda: read_recorded(root),
    }
    messages = set()
    for name, read in readers.items():
        with pytest.raises(ConfigError) as err:
            read()
        messages.add(str(err.value))
        assert "'gripper_tilt'" in str(err.value) and f"lerobot_pnp {__version__} does not know" in str(err.value), name
    assert len(messages) == 1, messages
    assert not (tmp_path / "baxter_pnp_env.json").exists()  # nothing copied
    (root / "meta/pnp_generate.json").write_text(json.dumps({"lerobot_pnp_version": "9.0.0"}))  # who generated it
    with pytest.raises(ConfigError, match=r"lerobot_pnp 9\.0\.0 generated the dataset: read it with that version"):
        dataset_task(root)


# ------------------------------------------------------------------------------------- stock lerobot-train
# The stock script through a launcher that can hide the plugin's distribution from LeRobot's discovery (the same
# Python and LeRobot otherwise): PNP_WITHOUT_PLUGIN=1 runs it as if the plugin were not installed.
_TRAIN = r"""
import importlib.metadata as md, os, sys
if os.environ.get("PNP_WITHOUT_PLUGIN"):
    _all = md.distributions
    md.distributions = lambda *a, **k: (d for d in _all(*a, **k) if d.metadata.get("Name") != "lerobot_policy_pnp_lstm")
sys.argv = ["lerobot-train", *sys.argv[1:]]
from lerobot.scripts.lerobot_train import main
sys.exit(main())
"""
TINY_ACT = ["--policy.type=act", "--policy.device=cpu", "--policy.push_to_hub=false", "--policy.dim_model=16",
            "--policy.n_heads=2", "--policy.dim_feedforward=32", "--policy.n_encoder_layers=1",
            "--policy.n_decoder_layers=1", "--policy.chunk_size=4", "--policy.n_action_steps=4",
            "--policy.use_vae=false", "--batch_size=4", "--num_workers=0", "--seed=1", "--wandb.enable=false"]  # fmt: skip


def _train(root: Path, out: Path, repo_id: str, without_plugin: bool = False, steps: int = 2) -> subprocess.Popen:
    args = [f"--dataset.repo_id={repo_id}", f"--dataset.root={root}", *TINY_ACT, f"--steps={steps}"]
    args += [f"--save_freq={steps}", f"--output_dir={out}"]
    env = {**PLAIN_ENV, **({"PNP_WITHOUT_PLUGIN": "1"} if without_plugin else {})}
    return subprocess.Popen(
        [sys.executable, "-c", _TRAIN, *args], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def _other_robot_dataset(root: Path) -> None:
    """Two episodes of a robot that is not Baxter: a 4-d state, a 2-d scene state, a 3-d action."""
    import numpy as np
    from lerobot.datasets import LeRobotDataset

    feats = {
        "observation.state": {"dtype": "float32", "shape": (4,), "names": ["a", "b", "c", "d"]},
        "observation.environment_state": {"dtype": "float32", "shape": (2,), "names": ["x", "y"]},
        "action": {"dtype": "float32", "shape": (3,), "names": ["u", "v", "w"]},
    }
    ds = LeRobotDataset.create("test/other_robot", fps=10, features=feats, root=root, robot_type="other")
    rng = np.random.default_rng(0)
    for _ in range(2):
        for _ in range(12):
            frame = {k: rng.normal(size=f["shape"]).astype(np.float32) for k, f in feats.items()}
            ds.add_frame({**frame, "task": "move"})
        ds.save_episode()
    ds.finalize()


def _normalised(path: Path, outs: tuple[Path, Path]) -> bytes:
    """A checkpoint file's bytes, its run's output folder written as OUT (the one thing two runs may differ in)."""
    data = path.read_bytes()
    for out in sorted(outs, key=lambda o: -len(str(o))):  # "…/without" before its prefix "…/with"
        data = data.replace(str(out).encode(), b"OUT")
    return data


@pytest.mark.slow
def test_lerobot_train_on_another_robots_dataset_writes_the_same_checkpoint_with_and_without_the_plugin(tmp_path):
    root = tmp_path / "other"
    _other_robot_dataset(root)
    outs = (tmp_path / "with", tmp_path / "without")
    procs = [_train(root, out, "test/other_robot", without_plugin=i == 1) for i, out in enumerate(outs)]
    results = [(p, *p.communicate(timeout=240)) for p in procs]
    for proc, _, err in results:
        assert proc.returncode == 0, err[-3000:]
    with_files = sorted(p.relative_to(outs[0]) for p in (outs[0] / "checkpoints").rglob("*") if p.is_file())
    without_files = sorted(p.relative_to(outs[1]) for p in (outs[1] / "checkpoints").rglob("*") if p.is_file())
    assert with_files == without_files and any(p.name == "model.safetensors" for p in with_files), with_files
    for rel in with_files:
        assert _normalised(outs[0] / rel, outs) == _normalised(outs[1] / rel, outs), rel
    for _, out, err in results:
        assert "pnp" not in (out + err).lower() and "baxter" not in (out + err).lower()  # nothing of ours is said


@pytest.fixture(scope="module")
def our_dataset(tmp_path_factory) -> Path:
    from lerobot_pnp.dataset import GenerateConfig, generate

    root = tmp_path_factory.mktemp("ours") / "data"
    generate(GenerateConfig(repo_id="local/ours", root=str(root), num_episodes=2, seed=0, workers=1, progress=False))
    return root


@pytest.mark.slow
def test_stock_lerobot_train_on_our_dataset_with_an_invalid_recorded_task_stops_at_start_up(our_dataset, tmp_path):
    import shutil

    root = tmp_path / "data"
    shutil.copytree(our_dataset, root)
    record = json.loads((root / RECORDED_FILE).read_text())
    (root / RECORDED_FILE).write_text(json.dumps({**record, "hover_height": float("nan")}))
    out = tmp_path / "out"
    proc = _train(root, out, "local/ours", steps=4)
    _, err = proc.communicate(timeout=240)
    assert proc.returncode == 2, err[-3000:]
    assert "Traceback" not in err, err[-3000:]
    assert f"lerobot-train: error: the recorded env config {root / RECORDED_FILE} has non-finite values in " in err
    assert "Creating dataset" in err and "Start offline training" not in err  # before the dataset is even loaded
    assert not (out / "checkpoints").exists()


# ------------------------------------------------------------------------------------- stock lerobot-eval
def _checkpoint(out: Path, config, state_dim: int) -> Path:
    """A saved policy with its processors: ``config`` (a LeRobot policy config) on a robot with ``state_dim``
    joints, the scene's 3-d object position and an 8-d action."""
    import torch
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    dims = {"observation.state": state_dim, "observation.environment_state": 3, "action": 8}
    kinds = {"observation.state": FeatureType.STATE, "observation.environment_state": FeatureType.ENV}
    config.input_features = {k: PolicyFeature(kinds[k], (dims[k],)) for k in kinds}
    config.output_features = {"action": PolicyFeature(FeatureType.ACTION, (8,))}
    policy = get_policy_class(config.type)(config)
    stats = {k: {"mean": torch.zeros(n), "std": torch.ones(n)} for k, n in dims.items()}
    pre, post = make_pre_post_processors(config, dataset_stats=stats)
    for obj in (policy, pre, post):
        obj.save_pretrained(out)
    return out


@pytest.fixture
def misfit_and_truncated(tmp_path) -> tuple[Path, Path]:
    """An ACT checkpoint trained for another robot (14 joints), and a pnp_lstm checkpoint that fits the env but
    whose normaliser file is truncated."""
    from lerobot.policies.act.configuration_act import ACTConfig

    from lerobot_pnp.policy import PnpLstmConfig

    act = ACTConfig(dim_model=16, n_heads=2, dim_feedforward=32, n_encoder_layers=1, n_decoder_layers=1,
                    chunk_size=4, n_action_steps=4, use_vae=False, push_to_hub=False)  # fmt: skip
    misfit = _checkpoint(tmp_path / "act", act, state_dim=14)
    truncated = _checkpoint(tmp_path / "pnp", PnpLstmConfig(hidden_size=8, push_to_hub=False), state_dim=8)
    (normaliser,) = truncated.glob("policy_preprocessor_step_*normalizer*.safetensors")
    normaliser.write_bytes(normaliser.read_bytes()[: normaliser.stat().st_size // 2])
    return misfit, truncated


MISFIT = "policy of type 'act' does not fit the Baxter pick-and-place env: input 'observation.state' has shape (14,)"


def test_lerobot_evals_policy_builders_on_our_env_refuse_what_cannot_load_as_policy_errors(
    misfit_and_truncated, monkeypatch
):
    """``lerobot-eval``'s make_policy / make_pre_post_processors, as the plugin wraps them in that script: for our
    env a misfit or damaged checkpoint is a PolicyError; for another env LeRobot's functions run unchanged."""
    import types

    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import make_policy, make_pre_post_processors

    from lerobot_pnp.errors import PolicyError
    from lerobot_pnp.integration.stock_eval import EVAL_MODULE, install_stock_eval_hooks

    module = types.SimpleNamespace(make_policy=make_policy, make_pre_post_processors=make_pre_post_processors)
    monkeypatch.setitem(sys.modules, EVAL_MODULE, module)
    assert install_stock_eval_hooks() and install_stock_eval_hooks()  # idempotent: wrapped once
    assert module.make_policy.__wrapped__ is make_policy
    misfit, truncated = misfit_and_truncated
    env = BaxterPnPEnvConfig()
    for ckpt, message in ((misfit, MISFIT), (truncated, f"cannot load the policy from {truncated}: SafetensorError")):
        cfg = PreTrainedConfig.from_pretrained(ckpt)
        cfg.pretrained_path = ckpt
        with pytest.raises(PolicyError, match=re.escape(message)):
            module.make_policy(cfg=cfg, env_cfg=env)
            module.make_pre_post_processors(policy_cfg=cfg, pretrained_path=str(ckpt))
    cfg = PreTrainedConfig.from_pretrained(truncated)  # not built for our env: LeRobot's own error
    with pytest.raises(Exception) as err:
        module.make_pre_post_processors(policy_cfg=cfg, pretrained_path=str(truncated))
    assert not isinstance(err.value, PolicyError)


@pytest.mark.slow
def test_lerobot_eval_on_our_env_of_a_checkpoint_it_cannot_load_is_one_line(misfit_and_truncated, tmp_path):
    """Through the real ``lerobot-eval``: one line naming the problem, no traceback."""
    _, truncated = misfit_and_truncated
    cmd = [str(BIN / "lerobot-eval"), f"--policy.path={truncated}", "--env.type=baxter_pnp", "--eval.n_episodes=1"]
    cmd += ["--eval.batch_size=1", "--policy.device=cpu", f"--output_dir={tmp_path / 'eval'}"]
    proc = subprocess.run(cmd, env=PLAIN_ENV, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    line = f"lerobot-eval: error: cannot load the policy from {truncated}: SafetensorError:"
    assert line in proc.stderr.strip().splitlines()[-2], proc.stderr[-1000:]
