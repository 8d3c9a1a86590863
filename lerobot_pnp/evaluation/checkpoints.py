"""The one strict loader of a LeRobot policy checkpoint (any registered policy type), checked against this env.

``load_policy`` accepts a ``pretrained_model`` folder, a checkpoint step folder or a training run folder. It
checks that the checkpoint fits this env (``observation.state`` (8,), ``observation.environment_state`` of one
of the widths a task can give (``ENV_STATE_WIDTHS``; exactly the env's with ``env_cfg``) unless it sees the
scene through cameras, images ``observation.images.<camera>`` only of the env's cameras, ``action`` (8,)) and
that its weights and normalisation stats are finite; it raises ``IncompatiblePolicyError`` /
``PolicyLoadError`` (one line) otherwise. With ``env_cfg`` the policy is built the way ``lerobot-eval`` builds
it (``make_policy(cfg, env_cfg=...)``: the study's path); without, from the checkpoint alone (the viewer's and
DAgger's path). ``policy_action`` is one step of it; ``lerobot_pnp.closed_loop`` runs it for whole episodes.
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from lerobot.utils.constants import ACTION, OBS_IMAGES, OBS_STATE
from lerobot.utils.constants import OBS_ENV_STATE as OBS_ENV

from lerobot_pnp import robot
from lerobot_pnp.errors import PolicyError

CONFIG_NAME = "config.json"


class PolicyLoadError(PolicyError):
    """The policy checkpoint is missing or cannot be read."""


class IncompatiblePolicyError(PolicyError):
    """The checkpoint's features do not match this env (e.g. a checkpoint trained for another robot)."""


@dataclass
class LoadedPolicy:
    """A policy ready to run: the module, its processors and where it came from."""

    policy: Any  # lerobot PreTrainedPolicy
    preprocessor: Any
    postprocessor: Any
    path: Path
    type: str

    def reset(self) -> None:
        self.policy.reset()
        for proc in (self.preprocessor, self.postprocessor):
            reset = getattr(proc, "reset", None)
            if callable(reset):
                reset()

    def act(self, obs: dict, task: str = robot.TASK) -> np.ndarray:
        """One step on a single gym observation (``policy_action``)."""
        return policy_action(self, obs, task)


def resolve_checkpoint(path: str | Path) -> Path:
    """The ``pretrained_model`` folder for ``path`` (accepts it, a checkpoint step folder or a run folder)."""
    p = Path(path).expanduser()
    for candidate in (p, p / "pretrained_model", p / "checkpoints" / "last" / "pretrained_model"):
        if (candidate / CONFIG_NAME).is_file():
            return candidate
    if not p.exists():
        raise PolicyLoadError(f"policy checkpoint not found: {p} does not exist")
    raise PolicyLoadError(
        f"no policy checkpoint at {p}: expected a LeRobot 'pretrained_model' folder with {CONFIG_NAME} "
        "(or a checkpoint folder containing one)"
    )


# environment_state widths a task can give: object xyz [+ (sin 4 yaw, cos 4 yaw)] [+ goal xy] [+ phase one-hot]
ENV_STATE_WIDTHS = tuple(
    sorted(
        {robot.OBJECT_DIM + yaw + goal + phase for yaw in (0, 2) for goal in (0, 2) for phase in (0, robot.N_KEYFRAMES)}
    )
)


def image_inputs(config: Any) -> dict[str, tuple[int, int]]:
    """The camera inputs of a policy: ``{camera: (height, width)}`` from its ``observation.images.<camera>``."""
    prefix = f"{OBS_IMAGES}."
    feats = (config.input_features or {}).items()
    return {k[len(prefix) :]: tuple(ft.shape)[-2:] for k, ft in feats if k.startswith(prefix) and len(ft.shape) == 3}


def rendered_cameras(env_cfg: Any) -> dict[str, tuple[int, int]]:
    """The cameras an env config renders: ``{camera: (height, width)}``."""
    return {cam: (env_cfg.image_height, env_cfg.image_width) for cam in env_cfg.cameras}


def check_policy_features(
    config: Any, env_state_dim: int | None = None, cameras: dict[str, tuple[int, int]] | None = None
) -> None:
    """Raise ``IncompatiblePolicyError`` unless the policy's features are those of this env (with an
    ``environment_state`` of ``env_state_dim``, or of any width a task can give when None; camera inputs
    among the env's cameras, of the size ``cameras`` renders them at when given)."""
    from lerobot_pnp.presets import CAMERAS

    inputs = dict(config.input_features or {})
    outputs = dict(config.output_features or {})
    images = image_inputs(config)
    expected_in = {OBS_STATE: (robot.STATE_DIM,), OBS_ENV: (env_state_dim or robot.OBJECT_DIM,)}
    if images and OBS_ENV not in inputs:
        del expected_in[OBS_ENV]  # an image policy may see the object only through its cameras
    problems = []
    for cam, size in images.items():
        if cam not in CAMERAS:
            problems.append(f"image input '{OBS_IMAGES}.{cam}': the env's cameras are {list(CAMERAS)}")
        elif cameras is not None and cameras.get(cam) != size:
            got = (
                f"renders it at {cameras[cam][0]}x{cameras[cam][1]} (--env.image_height/--env.image_width)"
                if cam in cameras
                else f"does not render it (--env.cameras {sorted(cameras)})"
            )
            problems.append(f"image input '{OBS_IMAGES}.{cam}' is {size[0]}x{size[1]}; the env {got}")
    inputs = {
        k: v for k, v in inputs.items() if not k.startswith(f"{OBS_IMAGES}.") or k[len(OBS_IMAGES) + 1 :] not in images
    }
    for key, shape in expected_in.items():
        if key not in inputs:
            problems.append(f"missing input feature '{key}' (shape {shape})")
        elif key == OBS_ENV and env_state_dim is None and tuple(inputs[key].shape) in {(w,) for w in ENV_STATE_WIDTHS}:
            continue
        elif tuple(inputs[key].shape) != shape:
            problems.append(f"input '{key}' has shape {tuple(inputs[key].shape)}, this env gives {shape}")
    extra = sorted(set(inputs) - set(expected_in))
    if extra:
        problems.append(f"inputs {extra} are not produced by this env (it gives {sorted(expected_in)})")
    if ACTION not in outputs:
        problems.append(f"missing output feature '{ACTION}'")
    elif tuple(outputs[ACTION].shape) != (robot.ACTION_DIM,):
        problems.append(
            f"action has shape {tuple(outputs[ACTION].shape)}, this env takes ({robot.ACTION_DIM},) "
            "(7 joint targets + gripper)"
        )
    if problems:
        raise IncompatiblePolicyError(
            f"policy of type '{getattr(config, 'type', '?')}' does not fit the Baxter pick-and-place env: "
            + "; ".join(problems)
        )


def load_policy(path: str | Path, device: str = "cpu", env_cfg: Any = None) -> LoadedPolicy:
    """Load a LeRobot checkpoint with its processors, checked against this env.

    With ``env_cfg`` (a ``BaxterPnPEnvConfig``) the policy is built by ``make_policy(cfg, env_cfg=env_cfg)``,
    exactly as ``lerobot-eval`` does (its features become the env's; no postprocessor override); without,
    by its class's ``from_pretrained`` with the postprocessor on the CPU (the actions go to the env as numpy)."""
    from lerobot.configs import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_policy, make_pre_post_processors

    import lerobot_pnp.policy  # noqa: F401  (registers pnp_lstm)

    ckpt = resolve_checkpoint(path)
    try:
        config = PreTrainedConfig.from_pretrained(ckpt)
    except Exception as err:  # draccus / json errors: unknown policy type, corrupt file
        raise PolicyLoadError(f"cannot read the policy config {ckpt / CONFIG_NAME}: {err}") from err
    if env_cfg is not None:
        check_policy_features(config, len(env_cfg.environment_state_names), rendered_cameras(env_cfg))
    else:
        check_policy_features(config)
    # lerobot issue #4647: set pretrained_path by hand, or the processors are rebuilt without their stats.
    config.pretrained_path = ckpt
    config.device = device
    overrides = {"preprocessor_overrides": {"device_processor": {"device": device}}}
    try:
        # LeRobot's from_pretrained prints "Loading weights from local directory" on every load: a study or a
        # DAgger run loads a checkpoint per evaluation, and the line would double the length of its log
        with contextlib.redirect_stdout(io.StringIO()):
            if env_cfg is not None:
                policy = make_policy(cfg=config, env_cfg=env_cfg)
            else:
                policy = get_policy_class(config.type).from_pretrained(ckpt, config=config)
                overrides["postprocessor_overrides"] = {"device_processor": {"device": "cpu"}}
        preprocessor, postprocessor = make_pre_post_processors(config, pretrained_path=str(ckpt), **overrides)
    except Exception as err:
        raise PolicyLoadError(f"cannot load the policy from {ckpt}: {err}") from err
    check_checkpoint_values(ckpt, policy, (preprocessor, postprocessor))
    policy.eval()
    return LoadedPolicy(policy, preprocessor, postprocessor, ckpt, config.type)


_FLAGGED: set[tuple[Path, str]] = set()  # (checkpoint, feature) whose std 0 was already flagged


def check_checkpoint_values(ckpt: Path, policy: Any, processors: tuple) -> None:
    """A checkpoint whose weights or normalisation stats hold NaN/inf is the checkpoint's fault, named here
    (otherwise it surfaces steps later as a NaN action); a stat with std 0 is flagged (any change of that
    feature is then amplified by 1/eps)."""
    import logging

    from lerobot_pnp.policy.weights import non_finite_weights

    if bad := non_finite_weights(policy.state_dict()):
        raise PolicyLoadError(f"the checkpoint {ckpt} is corrupt: its weights {bad[0]!r} contain NaN/inf")
    for proc in processors:
        for step in getattr(proc, "steps", []):
            used = getattr(step, "features", None) or {}  # the features it normalises (not task_index, ...)
            for feature, stats in (getattr(step, "stats", None) or {}).items():
                for stat, value in stats.items():
                    array = np.asarray(value.cpu() if hasattr(value, "cpu") else value, dtype=np.float64)
                    if not np.all(np.isfinite(array)):
                        raise PolicyLoadError(
                            f"the checkpoint {ckpt} is corrupt: its normalisation stats {feature}.{stat} contain NaN/inf"
                        )
                    if stat == "std" and feature in used and np.any(array == 0) and (ckpt, feature) not in _FLAGGED:
                        _FLAGGED.add((ckpt, feature))  # once per checkpoint and process: a study loads it per suite
                        logging.getLogger(__name__).warning(
                            "checkpoint %s: %s has std 0 in dims %s (constant in its training data)",
                            ckpt, feature, np.flatnonzero(array.reshape(-1) == 0).tolist(),
                        )  # fmt: skip


def policy_action(loaded: LoadedPolicy, obs: dict, task: str) -> np.ndarray:
    """One policy step on a single (unbatched) gym observation; returns the (8,) env action."""
    import torch
    from lerobot.envs.utils import preprocess_observation

    keep_pixels = bool(image_inputs(loaded.policy.config))  # state policies never see the env's renders
    batch = preprocess_observation({k: v for k, v in obs.items() if k != "pixels" or keep_pixels})
    batch["task"] = [task]
    batch = loaded.preprocessor(batch)
    with torch.inference_mode():
        action = loaded.policy.select_action(batch)
    action = loaded.postprocessor(action)
    return action.to("cpu").numpy().reshape(-1).astype(np.float32)
