"""Episodes in the simulator: expert demonstrations, policy rollouts labelled by the expert, evaluation.

``FSMExpert(env).label()`` plans the expert's next keyframe from the current physical state without side
effects, so every state the *policy* visits gets the keyframe a perfect teacher would command there (DAgger).
The env is always built with ``make_env`` from an env config (the dataset's recorded task + the changes of a
suite of the one catalogue, ``lerobot_pnp.evaluation.suites``).
"""

from __future__ import annotations

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.errors import UnreachableError
from lerobot_pnp.evaluation.checkpoints import LoadedPolicy
from lerobot_pnp.evaluation.suites import SUITES

from .dart import DartNoise
from .writer import LabelledEpisode


def suite_env(base_cfg, suite: str):
    """The env for the catalogue's ``suite`` (one part): the base task config with its changes (``make_env``)."""
    from lerobot_pnp.env_config import make_env

    return make_env(SUITES[suite].env_configs(base_cfg)[0])


# A policy "followed" the last label when every joint setpoint is within this of it (rad): a learned keyframe
# lands a fraction of a degree from its label, a different keyframe is tens of degrees away.
FOLLOW_TOL = 0.05
# The teacher's rules for labelling a step the policy took (``Teacher``): part of the key of every rollout round
# in which the policy acts (beta < 1), so rollouts labelled by an older teacher are made again. In a round where the
# expert executes every step (beta = 1: the study's first DAgger round, DART) each label is followed, and the
# labels are those of every version. 2: a hold leaves the label pending; "followed" reads the gripper too.
TEACHER_VERSION = 2


class Teacher:
    """The expert's FSM continued along a trajectory, so its labels match the expert's demonstrations.

    ``FSMExpert.label()`` plans from the physical state alone. On expert trajectories that differs from the
    demonstrating FSM in three states (every other label equals the demonstrated keyframe):

    * after the pick retract the FSM holds once (place/start, the paper's state 4); ``label()`` goes straight
      to the place approach;
    * after the place descent the FSM opens the gripper; ``label()`` plans the descent again (the object is
      still a clearance above the table, so its inferred phase has not advanced);
    * when the object slid away during the grasp descent the FSM closes, finds the gripper empty, lifts with
      it open and re-approaches; ``label()`` re-approaches at once.

    Mixing both teachers gives contradictory targets for the same state (a DAgger round trained on both did
    much worse). So the teacher keeps the demonstrating FSM's state along the rollout:

    * when the previous label was followed (the arm's setpoints at its target and the gripper commanded to
      its side), it plans from the next FSM state, as the demonstrating expert does (with the expert's own
      checks for a miss, a drop or a displacement);
    * when nothing new was commanded since the previous label (the arm's setpoints and the gripper command
      as they were: the policy held), that label is still pending: it plans from the same FSM state again
      (with the same checks, so an event in between still starts a recovery);
    * otherwise, and at the first step, it is ``label()``.

    Both conditions read the gripper too. A policy that sees its observations late often holds a step where
    the expert moves on (it has not seen its last move arrive), and the close and the open are keyframes that
    keep the arm where it is: judged by the arm alone, a close that did not happen passed for one that missed
    (the next label lifted with the gripper open) and a hold passed for a policy that went elsewhere.
    """

    def __init__(self, env):
        from lerobot_pnp.expert import FSMExpert

        self.expert = FSMExpert(env)
        self.physics = env.unwrapped.physics
        self.prev: tuple[robot.Phase, np.ndarray] | None = None
        self.before: np.ndarray | None = None  # the command (arm and gripper) when ``prev`` was made; set with it

    def _command(self) -> np.ndarray:
        return np.append(self.physics.arm_command(), self.physics.gripper_command()).astype(np.float32)

    def label(self) -> tuple[np.ndarray, robot.Phase]:
        prev, command = self.prev, self._command()
        if prev is not None and follows(command, prev[1]):
            self._plan_from(robot.Phase(min(prev[0] + 1, robot.N_KEYFRAMES - 1)))
            keyframe, phase = self.expert.next_keyframe(), self.expert.last_phase
        elif prev is not None and follows(command, self.before):
            self._plan_from(prev[0])
            keyframe, phase = self.expert.next_keyframe(), self.expert.last_phase
        else:
            keyframe, phase = self.expert.label()
        self.prev, self.before = (phase, keyframe), command
        return keyframe, phase

    def _plan_from(self, phase: robot.Phase) -> None:
        self.expert.sync_to_state()
        self.expert.phase = phase

    def executed(self, action: np.ndarray) -> None:
        """The teacher's last label was executed as ``action`` (itself, or with DART's noise): the next label
        continues its FSM, as the demonstrating expert continues after commanding a keyframe. (Compared with
        the label alone, a joint noised past ``FOLLOW_TOL`` would make it replan with ``FSMExpert.label()``,
        whose labels differ from the demonstrations in the states listed above.)"""
        assert self.prev is not None, "executed() before label()"
        self.prev = (self.prev[0], np.asarray(action, np.float32))


def labelled_rollout(
    env, policy: LoadedPolicy, seed: int, suite: str = "", beta: float = 0.0, dart: DartNoise | None = None
) -> LabelledEpisode:
    """Run from ``env.reset(seed)`` until the env ends the episode; label every visited state (including the
    last) with the expert's next keyframe and phase.

    At each step the expert's label is executed with probability ``beta`` and the policy's action otherwise
    (Ross et al.'s mixture policy; ``beta = 0``: always the policy's). The policy acts at every step either
    way, so its recurrent state has seen the whole history when it takes over. With ``dart`` the expert's
    executed label carries DART's noise (``dagger.dart``) while the frame keeps the clean label. The draws
    come from generators seeded by ``seed``: a rollout is deterministic. ``info["executed"]`` counts the
    steps that executed the label, ``info["disagree"]`` those whose executed action was not the label (a
    joint more than ``FOLLOW_TOL`` from it, or the other gripper command), ``info["policy_disagree"]`` those
    where the policy's own action was not: the frames that teach the policy something.

    Each frame records the observation as it is at that step (with the task's noise and bias), also when the
    env's observations are late (``obs_latency``): the label is the expert's command for the current state, and a
    planner trained with latency augmentation (``policy.latency_augment_*``) is shown the frames late as the env
    shows them; a recorded late view would be shown later still.

    When the policy has pushed the object where the expert has no IK solution (``UnreachableError``), the
    episode ends there: the states before it keep their labels (``info["stopped"] = "unreachable"``)."""
    policy.reset()
    obs, info = env.reset(seed=seed)
    expert = Teacher(env)
    mix = np.random.default_rng(seed)
    dart, noise = dart or DartNoise(), DartNoise.rng_for(seed)  # off: apply() returns the label, draws nothing
    states, env_states, labels, phases = [], [], [], []
    done, stopped, executed, disagree, policy_disagree = False, None, 0, 0, 0
    while True:
        try:
            keyframe, phase = expert.label()
        except UnreachableError:
            if not labels:
                raise
            stopped, info = "unreachable", {**info, "is_success": False}
            break
        now = env.unwrapped.pnp_task.latest_observation  # the current state, not the late view the policy got
        states.append(np.asarray(now["agent_pos"], np.float32))
        env_states.append(np.asarray(now["environment_state"], np.float32))
        labels.append(keyframe)
        phases.append(phase)
        if done:
            break
        action = np.asarray(policy.act(obs), np.float32)
        policy_disagree += int(not follows(action, keyframe))
        if beta > 0.0 and mix.random() < beta:
            action = dart.apply(keyframe, noise)
            expert.executed(action)
            executed += 1
        disagree += int(not follows(action, keyframe))
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    return LabelledEpisode(
        seed,
        np.stack(states),
        np.stack(env_states),
        np.stack(labels).astype(np.float32),
        np.asarray(phases, np.int64),
        bool(info.get("is_success", False)),
        suite,
        {"failure_cause": info.get("failure_cause"), "furthest_phase": info.get("furthest_phase"), "stopped": stopped,
         "executed": executed, "disagree": disagree, "policy_disagree": policy_disagree},
    )  # fmt: skip


def joints_at(joints: np.ndarray, keyframe: np.ndarray) -> bool:
    """Whether arm joint setpoints are ``keyframe``'s (every joint within ``FOLLOW_TOL``)."""
    return bool(
        np.abs(np.asarray(joints)[: robot.N_JOINTS] - np.asarray(keyframe)[: robot.N_JOINTS]).max() < FOLLOW_TOL
    )


def follows(action: np.ndarray, label: np.ndarray) -> bool:
    """Whether an executed ``action`` is the ``label`` (its joints at the label's, the same gripper side)."""
    return joints_at(action, label) and bool((action[robot.N_JOINTS] > 0.5) == (label[robot.N_JOINTS] > 0.5))


def evaluate(policy: LoadedPolicy, base_cfg, suite: str, seeds: list[int], progress=None) -> dict:
    """Success of ``policy`` on ``suite`` over ``seeds`` (one env, seeded resets), with failures by cause."""
    from lerobot_pnp.closed_loop import evaluate_serial
    from lerobot_pnp.evaluation.records import summarize

    counts = summarize(evaluate_serial(policy, SUITES[suite].env_configs(base_cfg)[0], seeds, progress))
    return {"suite": suite, "n": counts["n"], "successes": counts["successes"], "failures": counts["by_cause"]}
