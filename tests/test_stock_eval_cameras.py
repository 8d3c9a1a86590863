"""A camera checkpoint evaluated with other cameras or another image size than it was trained on: refused when
``lerobot-eval`` builds the policy, in one line naming the policy type, the checkpoint's value and the one given,
before any rollout (nothing written); likewise the strict loader given the env config."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from clis import exe
from zygote import run

from lerobot_pnp.evaluation.checkpoints import IncompatiblePolicyError, load_policy
from lerobot_pnp.integration.recorded_task import write_checkpoint_task
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

SIZE = 32
REPO = Path(__file__).resolve().parents[1]
MISMATCHES = [  # (env changes, flag, what the one line says)
    ({"image_height": 48}, "--env.image_height=48", "is 32x32; the env renders it at 48x32"),
    ({"cameras": ["wrist"]}, "--env.cameras=[wrist]", "is 32x32; the env does not render it (--env.cameras ['wrist'])"),
]


@pytest.fixture(scope="module")
def pixels_checkpoint(tmp_path_factory) -> Path:
    """A tiny untrained pnp_pixels checkpoint recording the paper's task seen by the front camera at 32x32."""
    import torch
    from lerobot.configs.types import FeatureType, PolicyFeature

    from lerobot_pnp.policy import PnpPixelsConfig, PnpPixelsPolicy
    from lerobot_pnp.policy.processor_pnp_pixels import make_pnp_pixels_pre_post_processors

    task = BaxterPnPEnvConfig(preset="paper", cameras=["front"], image_height=SIZE, image_width=SIZE)
    cfg = PnpPixelsConfig(hidden_size=8, conv_channels=[4], num_keypoints=2)
    cfg.input_features = {
        "observation.state": PolicyFeature(type=FeatureType.STATE, shape=(8,)),
        "observation.images.front": PolicyFeature(type=FeatureType.VISUAL, shape=(3, SIZE, SIZE)),
    }
    cfg.output_features = {"action": PolicyFeature(type=FeatureType.ACTION, shape=(8,))}
    stats = {
        k: {"mean": np.zeros(8, np.float32), "std": np.ones(8, np.float32)} for k in ("observation.state", "action")
    }
    path = tmp_path_factory.mktemp("pixels") / "pretrained_model"
    torch.manual_seed(0)
    PnpPixelsPolicy(cfg).save_pretrained(path)
    for processor in make_pnp_pixels_pre_post_processors(cfg, stats):
        processor.save_pretrained(path)
    write_checkpoint_task({"type": "baxter_pnp", **task.to_dict()}, path)
    return path


@pytest.mark.parametrize(("changes", "flag", "message"), MISMATCHES)
def test_the_stock_eval_hook_refuses_other_cameras_before_building_the_policy(
    pixels_checkpoint, changes, flag, message
):
    """lerobot-eval's make_policy, as the plugin wraps it: the env config of the run against the checkpoint."""
    from lerobot.configs import PreTrainedConfig

    from lerobot_pnp.integration.stock_eval import _checked_make_policy

    built = []
    make_policy = _checked_make_policy(lambda *args, **kwargs: built.append(args))
    cfg = PreTrainedConfig.from_pretrained(pixels_checkpoint)
    cfg.pretrained_path = pixels_checkpoint
    env_cfg = BaxterPnPEnvConfig.from_source(str(pixels_checkpoint), **changes)
    with pytest.raises(IncompatiblePolicyError) as err:
        make_policy(cfg, env_cfg=env_cfg)
    assert str(err.value).startswith("policy of type 'pnp_pixels' does not fit") and message in str(err.value)
    assert not built
    make_policy(cfg, env_cfg=BaxterPnPEnvConfig.from_source(str(pixels_checkpoint)))  # its own task: built
    assert len(built) == 1


@pytest.mark.parametrize(("changes", "flag", "message"), MISMATCHES)
def test_the_strict_loader_refuses_other_cameras(pixels_checkpoint, changes, flag, message):
    env_cfg = BaxterPnPEnvConfig.from_source(str(pixels_checkpoint), **changes)
    with pytest.raises(IncompatiblePolicyError, match="pnp_pixels") as err:
        load_policy(pixels_checkpoint, env_cfg=env_cfg)
    assert message in str(err.value)
    assert load_policy(pixels_checkpoint, env_cfg=BaxterPnPEnvConfig.from_source(str(pixels_checkpoint))).type == (
        "pnp_pixels"
    )


@pytest.mark.slow
def test_lerobot_eval_refuses_other_cameras_and_threads_in_one_line_writing_nothing(pixels_checkpoint, tmp_path):
    """lerobot-eval's entry point (in processes forked from a warm interpreter, tests/zygote.py): one error line,
    exit 2, no output folder (no empty videos/ left behind)."""
    evaluate = exe("lerobot-eval")
    args = [evaluate, f"--policy.path={pixels_checkpoint}", "--env.type=baxter_pnp", "--eval.n_episodes=1"]
    args += ["--eval.batch_size=1", "--policy.device=cpu"]
    cases = [(flag, message) for _, flag, message in MISMATCHES]
    cases.append(
        ("--env.max_parallel_tasks=2", "env.max_parallel_tasks=2: lerobot-eval would run the tasks in threads")
    )
    for i, (flag, message) in enumerate(cases):
        out = tmp_path / f"out{i}"
        proc = run([*args, flag, f"--output_dir={out}"], tmp_path, timeout=180)
        errors = [line for line in proc.stderr.splitlines() if ": error: " in line]
        assert proc.returncode == 2 and len(errors) == 1 and message in errors[0], proc.stderr[-3000:]
        assert "Traceback" not in proc.stderr and not out.exists(), proc.stderr[-3000:]
