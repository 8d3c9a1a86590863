"""Inside a stock ``lerobot-eval`` process on our env only: a checkpoint that cannot run there is one line.

``lerobot-eval --env.type=baxter_pnp --policy.path=<ckpt>`` builds the policy with LeRobot's ``make_policy`` and
its processors with ``make_pre_post_processors``. A checkpoint trained for another robot (an ACT with other state
or action sizes), or one whose files are damaged (a truncated normaliser ``.safetensors``), fails deep inside
LeRobot or safetensors with a long traceback. ``lerobot-pnp viz`` and ``train`` load the same files through the
strict loader (``evaluation.checkpoints``) and say in one line what is wrong. Here the two functions of the
``lerobot_eval`` module are wrapped the same way: for a run on our env, the policy's features are checked against
the env first (``check_policy_features``: its camera inputs rendered by the env at the size it was trained on,
before a rollout starts), and a failure to load is a ``PolicyLoadError`` naming the checkpoint
(printed as one line by ``stock_errors.install_cli_excepthook``). Any other env's run calls LeRobot's functions as
they are.
"""

from __future__ import annotations

import functools
import sys

EVAL_MODULE = "lerobot.scripts.lerobot_eval"
_ours: set[int] = set()  # ids of the policy configs make_policy built for our env in this process


def install_stock_eval_hooks() -> bool:
    """Wrap ``lerobot-eval``'s ``make_policy`` and ``make_pre_post_processors`` when this process runs it (True
    when the hooks are in place); installing twice wraps once."""
    module = sys.modules.get(EVAL_MODULE)
    if module is None or not hasattr(module, "make_policy"):
        return False
    for name, make in (("make_policy", _checked_make_policy), ("make_pre_post_processors", _checked_processors)):
        original = getattr(module, name)
        if not getattr(original, "pnp_hook", False):
            wrapper = functools.wraps(original)(make(original))
            wrapper.pnp_hook = True
            setattr(module, name, wrapper)
    return True


def _is_our_env(env_cfg) -> bool:
    from lerobot_pnp.presets import ENV_TYPE

    return getattr(env_cfg, "type", None) == ENV_TYPE


def _checked_make_policy(original):
    def make_policy(cfg, *args, **kwargs):
        env_cfg = kwargs.get("env_cfg")
        if not _is_our_env(env_cfg):
            return original(cfg, *args, **kwargs)
        from lerobot_pnp.evaluation.checkpoints import check_policy_features, rendered_cameras

        if getattr(cfg, "pretrained_path", None):  # a checkpoint: its features are the ones it was trained with
            check_policy_features(cfg, len(env_cfg.environment_state_names), rendered_cameras(env_cfg))
        _ours.add(id(cfg))
        return _loading(cfg, original, cfg, *args, **kwargs)

    return make_policy


def _checked_processors(original):
    def make_pre_post_processors(*args, **kwargs):
        cfg = kwargs.get("policy_cfg", args[0] if args else None)
        if id(cfg) not in _ours:
            return original(*args, **kwargs)
        return _loading(cfg, original, *args, **kwargs)

    return make_pre_post_processors


def _loading(cfg, function, *args, **kwargs):
    """``function(*args, **kwargs)``; any failure but ours is a ``PolicyLoadError`` naming the checkpoint."""
    from lerobot_pnp.errors import PnPError
    from lerobot_pnp.evaluation.checkpoints import PolicyLoadError

    try:
        return function(*args, **kwargs)
    except PnPError:
        raise
    except Exception as err:
        where = getattr(cfg, "pretrained_path", None) or f"a new {getattr(cfg, 'type', '?')} policy"
        raise PolicyLoadError(f"cannot load the policy from {where}: {type(err).__name__}: {err}") from err
