"""The catalogue's suites as stock ``lerobot-eval`` tasks: ``--env.task=<names>`` runs several suites in one process.

LeRobot 0.6.1's multi-suite contract (its ``adding_benchmarks`` guide, as LIBERO and Meta-World use it): an env
config's ``create_envs`` returns ``{suite: {task_id: VectorEnv}}``; ``lerobot-eval`` then runs every suite
(``eval_policy_all``) from the same ``--seed``, so episode ``i`` of every suite is seed ``--seed + i`` and the suites
are paired by seed, and writes ``per_task``, ``per_group`` (one entry per suite) and ``overall`` into
``eval_info.json``. Here every suite is one task (``task_id`` 0).

``--env.task`` takes comma-separated names (as LIBERO does): a suite of ``suites.SUITES``, a sweep group of it
(``nudge``), one axis of the held-out protocol (``heldout_<axis>``: its in-distribution and held-out suites, a
disturbance axis or a visual one), or an alias of a whole set: ``heldout`` (the held-out study's suites: ``nominal``
and every disturbance axis), ``heldout_visual`` (``nominal`` and every visual axis' suites) and ``paper`` (the
paper study's). The default, ``BaxterPnP-v0`` (the gymnasium id's suffix), is the one task of the config as given.

Each suite is ``Suite.env_configs`` of the resolved config (the task recorded with the checkpoint, with any
``--env.*`` flags on top): the study's own code, so a suite means the same in the study, in DAgger and here. The
names and each suite's config are checked when the config is built (``check_task``), before ``lerobot-eval`` loads
a policy or writes anything. A suite's vector env is built when ``lerobot-eval`` reaches it and closed after it, so
memory holds one suite's envs at a time; a sub-env whose episode ended stops simulating (LeRobot's
``FreezeAfterEpisodeEnd``) until the rollout's next seeded reset.

Videos: ``lerobot-eval`` always writes up to 10 episodes per task (``videos/<suite>_0/eval_episode_<i>.mp4``,
one frame per env step). A MuJoCo render costs about 20 keyframe steps on a CPU, so 10 rendered episodes per suite
would cost more than the 100 episodes they show; without cameras a suite's frames are top-down sketches drawn from
the simulator's state (``sketch_frame``: free), with cameras the front camera's renders (what the policy sees).
"""

from __future__ import annotations

import functools
from typing import Any

import gymnasium as gym
import numpy as np
from lerobot.envs.utils import FreezeAfterEpisodeEnd, _LazyAsyncVectorEnv

from lerobot_pnp.errors import ConfigError, shown
from lerobot_pnp.presets import GYM_ID, GYM_TASK

AXIS_PREFIX = "heldout_"


def _study_suites(preset: str) -> list[str]:
    """The suite names a study preset evaluates, sweep groups expanded (``suites.STUDY_SUITES``)."""
    from lerobot_pnp.sim.suites import STUDY_SUITES, get_suites

    return [s.name for name in STUDY_SUITES[preset] for s in get_suites([name])]


def _visual_suites() -> list[str]:
    from lerobot_pnp.sim.visual_suites import VISUAL_SUITES

    return ["nominal", *VISUAL_SUITES]


# alias -> (what it is, its suites); the study's presets are the one list of what each study evaluates
ALIASES = {
    "heldout": (
        "the held-out protocol: nominal and every disturbance axis",
        functools.partial(_study_suites, "heldout"),
    ),
    "heldout_visual": ("the visual axes of the held-out protocol: nominal and every visual suite", _visual_suites),
    "paper": ("the paper study's suites", functools.partial(_study_suites, "full")),
}


def _axes() -> dict[str, list[str]]:
    from lerobot_pnp.sim.suites import ALL_AXES

    return {f"{AXIS_PREFIX}{a.name}": list(a.in_distribution + a.held_out) for a in ALL_AXES}


def valid_names() -> list[str]:
    """Every name ``--env.task`` accepts besides the default: suites, sweep groups, axes, aliases."""
    from lerobot_pnp.sim.suites import SUITES

    groups = sorted({s.group for s in SUITES.values() if s.group})
    return [*SUITES, *groups, *_axes(), *ALIASES]


def suite_names(task: str | None) -> list[str] | None:
    """The suites ``--env.task`` names, in order, each once; None for the default (the config's one task)."""
    from lerobot_pnp.sim.suites import SUITES, get_suites

    if task is None or task == GYM_TASK:
        return None
    names = [n.strip() for n in str(task).split(",")]
    if not all(names):
        what = "is empty" if not any(names) else f"has an empty name in {shown(task)}"
        raise ConfigError(f"env.task {what}; give suite names, comma-separated, from {valid_names()}")
    axes, groups, out = _axes(), {s.group for s in SUITES.values() if s.group}, []
    for name in names:
        if name in ALIASES:
            out += ALIASES[name][1]()
        elif name in axes:
            out += axes[name]
        elif name in SUITES or name in groups:
            out += [s.name for s in get_suites([name])]
        else:
            raise ConfigError(
                f"env.task: unknown suite {shown(name)}; valid: {GYM_TASK} (the one task) or {valid_names()}"
            )
    return list(dict.fromkeys(out))


def suite_configs(cfg: Any) -> dict[str, Any] | None:
    """``{suite: env config}`` for the suites ``cfg.task`` names (None: the default task): each suite's changes on
    top of ``cfg`` as resolved (the recorded task and the flags), exactly as the study applies them."""
    from lerobot_pnp.sim.suites import SUITES

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
        _check_control_mode(name, part)
        out[name] = part
    return out


def _check_control_mode(name: str, part: Any) -> None:
    """A suite that nudges pushes the object "after the first keyframe": env step ``nudge_at_step`` = 1 in keyframe
    control. In dense control step 1 is one control period after the reset, before the arm has moved, a different
    suite; the study times it from the dense demonstrations, which a checkpoint does not carry. The nudge may be the
    suite's change or the task's own (on ``full`` every suite nudges), so the resolved config decides."""
    if part.control_mode == "dense" and part.nudge_max > 0 and part.nudge_at_step <= 1:
        raise ConfigError(
            f"env.task: suite {name!r} nudges the object at env step {part.nudge_at_step}, the first keyframe in "
            f"keyframe control; this checkpoint's task is in dense control ({part.fps} fps), where that step comes "
            "before the arm moves. Pass --env.nudge_at_step=<the dense step of the first keyframe> or leave the suite out"
        )


def check_task(cfg: Any) -> None:
    """Refuse a bad ``--env.task`` when the config is built (one ConfigError): unknown or no names, a suite whose
    changes do not apply to the resolved task. (Running tasks in threads, ``--env.max_parallel_tasks``, is refused
    for every task by ``env_validation``.)"""
    suite_configs(cfg)


def create_suite_envs(cfg: Any, n_envs: int, use_async_envs: bool) -> dict[str, dict[int, Any]] | None:
    """``{suite: {0: vector env}}`` for ``cfg.task``'s suites (None for the default task: the caller builds it)."""
    configs = suite_configs(cfg)
    if configs is None:
        return None
    return {name: {0: _vector_env(name, c, n_envs, use_async_envs)} for name, c in configs.items()}


def make_suite_env(config: dict, suite: str) -> gym.Env:
    """One sub-env of a suite: ``task`` is the suite's name (LeRobot's task name, as LIBERO's), ``task_description``
    the language instruction, which no suite changes; frozen once its episode ends. Its video frames are top-down
    sketches unless the config renders cameras (a policy that sees images gets the front camera's renders)."""
    env = gym.make(GYM_ID, disable_env_checker=True, config=config)
    env.unwrapped.task = suite
    return FrozenRender(env, sketch=not config.get("cameras"))


class FrozenRender(FreezeAfterEpisodeEnd):
    """LeRobot's ``FreezeAfterEpisodeEnd``, whose ``render`` while frozen is the frame of the frozen scene, drawn
    once: ``lerobot-eval`` renders its video episodes at every step of the batch until the batch's last episode
    ends. With ``sketch`` a frame is a top-down sketch of the scene (``sketch_frame``), not a MuJoCo render."""

    def __init__(self, env: gym.Env, sketch: bool = False):
        super().__init__(env)
        self._sketch = sketch
        self._still = None  # the frozen scene's frame

    def reset(self, **kwargs):
        obs, info = super().reset(**kwargs)
        if not self.is_frozen:
            self._still = None
        return obs, info

    def render(self):
        if self.is_frozen and self._still is not None:
            return self._still
        frame = sketch_frame(self.env.unwrapped) if self._sketch else self.env.render()
        self._still = frame if self.is_frozen else None
        return frame


SKETCH_SIZE = (120, 180)  # pixels: 0.6 m (base x, down) by 0.9 m (base y, right to left)
_ORIGIN, _SCALE = (0.3, 0.6), 200.0  # the sketch's top-left corner (base x, y in m) and its pixels per metre


def sketch_frame(env) -> np.ndarray:
    """The scene seen from above, from the simulator's state (a render costs about 20 keyframe steps on a CPU):
    the place target (green, its success tolerance), the cube (red, darker when lifted) and the gripper (blue,
    larger the higher it is, hollow when open)."""
    frame = np.full((*SKETCH_SIZE, 3), 235, np.uint8)
    physics, task = env.physics, env.pnp_task

    def box(xy, half: float, color, hollow: bool = False) -> None:
        r, c = (xy[0] - _ORIGIN[0]) * _SCALE, (_ORIGIN[1] - xy[1]) * _SCALE
        h = max(1, round(half * _SCALE))
        r0, r1, c0, c1 = (max(0, round(v)) for v in (r - h, r + h + 1, c - h, c + h + 1))
        frame[r0:r1, c0:c1] = color
        if hollow and r1 - r0 > 2 and c1 - c0 > 2:
            frame[r0 + 1 : r1 - 1, c0 + 1 : c1 - 1] = 235

    from lerobot_pnp import robot

    box(task.place_xy, env.config.success_xy_tol, (60, 170, 60))
    pos, _ = physics.object_pose()
    lifted = pos[2] > robot.TABLE_TOP_Z + physics.object_size
    box(pos[:2], physics.object_size / 2, (150, 20, 20) if lifted else (220, 50, 50))
    ee, _ = physics.ee_pose()
    box(
        ee[:2], 0.01 + 0.05 * max(0.0, ee[2] - robot.TABLE_TOP_Z), (40, 70, 200), hollow=physics.gripper_opening() > 0.5
    )
    return frame


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
