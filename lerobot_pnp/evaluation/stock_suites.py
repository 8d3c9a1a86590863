"""The catalogue's suites as stock ``lerobot-eval`` tasks: ``--env.task=<names>`` runs several suites in one process.

LeRobot 0.6.1's multi-suite contract (its ``adding_benchmarks`` guide, as LIBERO and Meta-World use it): an env
config's ``create_envs`` returns ``{suite: {task_id: VectorEnv}}``; ``lerobot-eval`` then runs every suite
(``eval_policy_all``) from the same ``--seed``, so episode ``i`` of every suite is seed ``--seed + i`` and the suites
are paired by seed, and writes ``per_task``, ``per_group`` (one entry per suite) and ``overall`` into
``eval_info.json``. Here every suite is one task (``task_id`` 0).

``--env.task`` takes comma-separated names (as LIBERO does): a suite of ``suites.SUITES``, a sweep group of it
(``nudge``), one axis of the held-out protocol (``heldout_<axis>``: its in-distribution and held-out suites), or an
alias of a whole set: ``heldout`` (the held-out study's suites: ``nominal`` and every axis) and ``paper`` (the
paper study's). The default, ``BaxterPnP-v0`` (the gymnasium id's suffix), is the one task of the config as given.

Each suite is ``Suite.env_configs`` of the resolved config (the task recorded with the checkpoint, with any
``--env.*`` flags on top): the study's own code, so a suite means the same in the study, in DAgger and here. The
names and each suite's config are checked when the config is built (``check_task``), before ``lerobot-eval`` loads
a policy or writes anything. A suite's vector env is built when ``lerobot-eval`` reaches it and closed after it, so
memory holds one suite's envs at a time; a sub-env whose episode ended stops simulating (LeRobot's
``FreezeAfterEpisodeEnd``) until the rollout's next seeded reset.
"""

from __future__ import annotations

import functools
from typing import Any

import gymnasium as gym
from lerobot.envs.utils import FreezeAfterEpisodeEnd, _LazyAsyncVectorEnv

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.presets import GYM_ID, GYM_TASK

AXIS_PREFIX = "heldout_"


def _study_suites(preset: str) -> list[str]:
    """The suite names a study preset evaluates, sweep groups expanded (``report.config.PRESETS``)."""
    from lerobot_pnp.evaluation.suites import get_suites
    from lerobot_pnp.report.config import PRESETS

    return [s.name for spec in PRESETS[preset]["suites"] for s in get_suites([spec.name])]


# alias -> (what it is, its suites); the study's presets are the one list of what each study evaluates
ALIASES = {
    "heldout": ("the held-out protocol: nominal and every axis", functools.partial(_study_suites, "heldout")),
    "paper": ("the paper study's suites", functools.partial(_study_suites, "full")),
}


def _axes() -> dict[str, list[str]]:
    from lerobot_pnp.evaluation.suites import HELD_OUT_AXES

    return {f"{AXIS_PREFIX}{a.name}": list(a.in_distribution + a.held_out) for a in HELD_OUT_AXES}


def valid_names() -> list[str]:
    """Every name ``--env.task`` accepts besides the default: suites, sweep groups, axes, aliases."""
    from lerobot_pnp.evaluation.suites import SUITES

    groups = sorted({s.group for s in SUITES.values() if s.group})
    return [*SUITES, *groups, *_axes(), *ALIASES]


def suite_names(task: str | None) -> list[str] | None:
    """The suites ``--env.task`` names, in order, each once; None for the default (the config's one task)."""
    from lerobot_pnp.evaluation.suites import SUITES, get_suites

    if task is None or task == GYM_TASK:
        return None
    names = [n.strip() for n in str(task).split(",")]
    if not any(names):
        raise ConfigError(f"env.task is empty; give suite names, comma-separated, from {valid_names()}")
    axes, out = _axes(), []
    for name in names:
        if name in ALIASES:
            out += ALIASES[name][1]()
        elif name in axes:
            out += axes[name]
        elif name in SUITES or any(s.group == name for s in SUITES.values()):
            out += [s.name for s in get_suites([name])]
        else:
            raise ConfigError(f"env.task: unknown suite {name!r}; valid: {GYM_TASK} (the one task) or {valid_names()}")
    return list(dict.fromkeys(out))


def suite_configs(cfg: Any) -> dict[str, Any] | None:
    """``{suite: env config}`` for the suites ``cfg.task`` names (None: the default task): each suite's changes on
    top of ``cfg`` as resolved (the recorded task and the flags), exactly as the study applies them."""
    from lerobot_pnp.evaluation.suites import SUITES

    names = suite_names(cfg.task)
    if names is None:
        return None
    base = cfg.with_changes(task=GYM_TASK)  # each suite's config is one task of the gymnasium id
    out = {}
    for name in names:
        suite = SUITES[name]
        if len(suite.parts) != 1:  # lerobot-eval starts every task at the same seed: no consecutive seed blocks
            raise ConfigError(
                f"env.task: suite {name!r} has {len(suite.parts)} parts; lerobot-eval runs one-part suites"
            )
        (part,) = suite.env_configs(base)
        _check_control_mode(name, suite.parts[0], part)
        out[name] = part
    return out


def _check_control_mode(name: str, changes: dict, part: Any) -> None:
    """A nudge suite pushes the object "after the first keyframe": env step ``nudge_at_step`` = 1 in keyframe
    control. In dense control step 1 is one control period after the reset, before the arm has moved, a different
    suite; the study times it from the dense demonstrations, which a checkpoint does not carry."""
    if part.control_mode == "dense" and changes.get("nudge_max", 0) > 0 and part.nudge_at_step <= 1:
        raise ConfigError(
            f"env.task: suite {name!r} nudges the object at env step {part.nudge_at_step}, the first keyframe in "
            f"keyframe control; this checkpoint's task is in dense control ({part.fps} fps), where that step comes "
            "before the arm moves. Pass --env.nudge_at_step=<the dense step of the first keyframe> or leave the suite out"
        )


def check_task(cfg: Any) -> None:
    """Refuse a bad ``--env.task`` when the config is built (one ConfigError): unknown or no names, a suite whose
    changes do not apply to the resolved task."""
    suite_configs(cfg)


def create_suite_envs(cfg: Any, n_envs: int, use_async_envs: bool) -> dict[str, dict[int, Any]] | None:
    """``{suite: {0: vector env}}`` for ``cfg.task``'s suites (None for the default task: the caller builds it)."""
    configs = suite_configs(cfg)
    if configs is None:
        return None
    return {name: {0: _vector_env(name, c, n_envs, use_async_envs)} for name, c in configs.items()}


def make_suite_env(config: dict, suite: str) -> gym.Env:
    """One sub-env of a suite: ``task`` is the suite's name (LeRobot's task name, as LIBERO's), ``task_description``
    the language instruction, which no suite changes; frozen once its episode ends."""
    env = gym.make(GYM_ID, disable_env_checker=True, config=config)
    env.unwrapped.task = suite
    return FrozenRender(env)


class FrozenRender(FreezeAfterEpisodeEnd):
    """LeRobot's ``FreezeAfterEpisodeEnd``, whose ``render`` while frozen is the frame of the frozen scene, rendered
    once: ``lerobot-eval`` renders its video episodes at every step of the batch until the batch's last episode
    ends, and a render costs about a keyframe step on a CPU."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self._still = None  # the frozen scene's frame

    def reset(self, **kwargs):
        obs, info = super().reset(**kwargs)
        if not self.is_frozen:
            self._still = None
        return obs, info

    def render(self):
        if not self.is_frozen:
            return self.env.render()
        if self._still is None:
            self._still = self.env.render()
        return self._still


def _vector_env(name: str, cfg: Any, n_envs: int, use_async_envs: bool):
    fns = [functools.partial(make_suite_env, cfg.to_dict(), name) for _ in range(n_envs)]
    probe = fns[0]()  # the spaces, and the suite's env checked before the rollout reaches it
    spaces = (probe.observation_space, probe.action_space, probe.metadata)
    probe.close()
    if use_async_envs and n_envs > 1:
        return _LazyAsyncVectorEnv(fns, *spaces)
    return LazySyncVectorEnv(fns, *spaces)


class LazySyncVectorEnv(gym.vector.SyncVectorEnv):
    """A ``SyncVectorEnv`` whose sub-envs are built at its first use (``lerobot-eval`` builds every suite's env
    before it runs the first): one suite's sub-envs in memory at a time. A ``SyncVectorEnv`` so that LeRobot's
    video callback renders only the episodes it keeps."""

    def __init__(self, env_fns, observation_space, action_space, metadata):
        self._env_fns, self._built = env_fns, False
        self.num_envs = len(env_fns)
        self.single_observation_space, self.single_action_space = observation_space, action_space
        self.metadata = metadata

    def build(self) -> None:
        if not self._built:
            self._built = True
            from gymnasium.vector import AutoresetMode

            super().__init__(self._env_fns, autoreset_mode=AutoresetMode.SAME_STEP)

    def __getattr__(self, name: str):
        """Attributes set by ``SyncVectorEnv.__init__`` (``envs``, ...) build it first."""
        if name.startswith("__") or self.__dict__.get("_built", True):
            raise AttributeError(name)
        self.build()
        return getattr(self, name)

    def reset(self, **kwargs):
        self.build()
        return super().reset(**kwargs)

    def step(self, actions):
        self.build()
        return super().step(actions)

    def call(self, name, *args, **kwargs):
        self.build()
        return super().call(name, *args, **kwargs)

    def get_attr(self, name):
        self.build()
        return super().get_attr(name)

    def close(self, **kwargs):
        if self._built:
            super().close(**kwargs)
