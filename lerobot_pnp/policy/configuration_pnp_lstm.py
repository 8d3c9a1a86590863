"""Configuration of the ``pnp_lstm`` policy: the LSTM task planner of de Magistris et al. 2016.

The policy learns the pick-and-place FSM from a *keyframe* dataset: every episode is exactly
``n_subtasks * steps_per_subtask`` frames (2 x 5 = 10: pick start/approach/grasp/close/retract, then place
start/approach/descend/open/retract). At frame ``k`` the input is the robot state and the object position,
the target is the next keyframe (joint targets + gripper command).

Training windows: every ``lerobot-train`` sample is one whole episode. The observation/action delta indices
are ``-(T-1) .. T-1`` around the sampled frame, so a window always contains its whole episode (frames outside
it are padded), and ``drop_n_last_frames = T-1`` makes LeRobot's ``EpisodeAwareSampler`` sample only the
first frame of each episode, so an epoch is one pass over the episodes, as in the paper and the fast path.
The eval split (``--dataset.eval_split``) iterates every frame without that sampler; its windows hold the
whole episode too, so the held-out loss is the plain per-episode MSE.

LeRobot finds the classes by naming convention: this module is ``configuration_pnp_lstm``, so
``PnpLstmConfig`` -> ``PnpLstmPolicy`` in ``modeling_pnp_lstm`` and ``make_pnp_lstm_pre_post_processors``
in ``processor_pnp_lstm`` (see ``lerobot.policies.factory``).

This module (like the whole ``lerobot_pnp.policy`` package) knows tensors and LeRobot features only.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

from lerobot.configs import FeatureType, NormalizationMode, PreTrainedConfig
from lerobot.optim import AdamConfig
from lerobot.optim.schedulers import CosineAnnealingWithWarmupSchedulerConfig, LRSchedulerConfig
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE

from lerobot_pnp.errors import ConfigError, PolicyError

from .options_pnp_lstm import LR_SCHEDULERS, MODES, STILL_ARM_PHASES, option_rules

logger = logging.getLogger(__name__)

__all__ = ["LR_SCHEDULERS", "MODES", "STILL_ARM_PHASES", "PnpLstmConfig"]


@PreTrainedConfig.register_subclass("pnp_lstm")
@dataclass
class PnpLstmConfig(PreTrainedConfig):
    """Hyper-parameters of the LSTM task planner.

    Architecture (paper defaults): one LSTM + Linear head per subtask (``shared_network=False``), the
    PICK net runs on frames ``0..steps_per_subtask-1`` and the PLACE net on the rest, starting from a
    zero hidden state. Loss: MSE on MEAN_STD-normalised actions.
    """

    n_obs_steps: int = 1
    """LeRobot's observation history length; must be 1 (the LSTM state is the history)."""
    device: str | None = "cpu"
    """Torch device of the policy. ``"cpu"``: a network this small (its parameter count is in the study's report)
    runs as fast on one CPU thread as on a GPU (LeRobot's default ``None`` auto-selects and logs a warning)."""
    push_to_hub: bool = False
    """LeRobot's default is True, which makes ``lerobot-train`` demand a ``--policy.repo_id``; here it is opt-in."""

    # MEAN_STD for the robot state, the object position (ENV) and the action.
    normalization_mapping: dict[str, NormalizationMode] = field(
        default_factory=lambda: {
            "STATE": NormalizationMode.MEAN_STD,
            "ENV": NormalizationMode.MEAN_STD,
            "ACTION": NormalizationMode.MEAN_STD,
        }
    )

    # Task structure.
    steps_per_subtask: int = 5
    """Keyframes per subtask FSM (the paper's 5 states)."""
    n_subtasks: int = 2
    """Number of subtasks (pick, place). An episode has ``n_subtasks * steps_per_subtask`` frames."""

    # Architecture.
    hidden_size: int = 128
    """LSTM hidden units."""
    num_layers: int = 1
    """Stacked LSTM layers (1 or 2). The recovering recipe stacks two: the second carries longer observation
    latency (docs/changelog.md); the memoryless MLP control is then matched to both layers' size."""
    dropout: float = 0.0
    """Dropout between stacked LSTM layers and before the Linear head (training only)."""
    shared_network: bool = False
    """One LSTM for all subtasks instead of one per subtask; a subtask one-hot is then appended to the input."""
    carry_hidden_across_subtasks: bool = False
    """Only with ``shared_network``: keep the hidden state across the subtask switch instead of resetting it to zero."""
    recurrent: bool = True
    """``False`` gives the memoryless ablation: the same layers, but the hidden state is reset to zero before every
    step (same parameter count, no memory)."""

    # Training.
    input_noise_std: float = 0.0
    """Std of Gaussian noise added to the normalised inputs during training only."""
    latency_augment_prob: float = 0.0
    """Training only: the probability that a training episode's observations are shown one step late (frame ``t``
    gets the observation of frame ``t-1``, frame 0 its own), with the actions unchanged. A policy trained on
    current observations only loses sync with its own history when they arrive a step late (the recovering LSTM then
    fails nearly every episode under ``obs_latency=1``); with both kinds of episode it learns to tell them apart from the first two frames
    (a delayed episode shows the start pose twice) and to act on stale observations. Works for the fast path and
    for ``lerobot-train`` (it acts on the whole-episode windows)."""
    latency_augment_max: int = 1
    """Training only: a late episode's lag is drawn uniformly in ``1..latency_augment_max`` steps (1: exactly one
    step late)."""
    latency_augment_jitter: float = 0.0
    """Training only: within a late episode the lag is redrawn in ``0..latency_augment_max`` at each frame with this
    probability (the env's ``obs_latency_jitter``)."""
    latency_augment_stretch: bool = False
    """Training only: a late episode's recovery is retimed as a late robot performs it (the first frame of the
    recovery repeated ``lag`` times, out of the loss; ``latency.late_observer``). Needs per-frame phase labels."""
    torch_num_threads: int | None = 1
    """If set and the policy runs on CPU, ``torch.set_num_threads`` is called with it when the policy is built. This
    tiny model runs many times slower with several intra-op threads on a small CPU (the threads' overhead dwarfs
    its matrix products); ``None`` leaves torch alone."""

    # Recorded from the training dataset.
    dataset_fps: int | None = None
    """Frame rate of the dataset the policy was trained on, recorded from the dataset's metadata when the policy is
    built for training (``None``: not recorded, e.g. checkpoints written before it was). A keyframe dataset has
    one frame per FSM state; evaluating on an env whose control rate differs (``--env.control_mode dense``) cannot
    work, and whoever builds the env can compare its ``fps`` with this (see ``check_env_fps``)."""

    # Optimiser preset (Adam, as in most LSTM work of the time).
    optimizer_lr: float = 1e-3
    """Adam preset."""
    optimizer_weight_decay: float = 0.0
    """Adam preset."""
    optimizer_grad_clip_norm: float = 10.0
    """Adam preset."""
    lr_scheduler: str = "none"
    """``"none"`` or ``"cosine"`` (linear warm-up, then cosine annealing to zero over the run)."""
    scheduler_warmup_steps: int = 0
    """Warm-up steps of the cosine schedule."""

    # Recovering mode (see recovering.py).
    mode: str = "clocked"
    """The planner: ``"clocked"`` (the paper's PICK/PLACE nets on a fixed 10-frame clock) or ``"recovering"``
    (one trunk over the whole episode, no clock, a learned PICK/PLACE switch; runs until the env ends it).

    The classes: ``clocked.ClockedPlanner`` (steps 0-4 PICK net, 5-9 PLACE net), ``recovering.RecoveringPlanner`` (state
    carried across the switch, PICK/PLACE heads mixed by a learned subtask classifier). In recovering mode
    ``recurrent=False`` is the memoryless control with an MLP trunk of about the LSTM trunk's parameter count;
    ``shared_network``, ``carry_hidden_across_subtasks`` and the subtask structure fields are not used (setting the
    first two is an error there)."""
    max_episode_length: int = 41
    """Recovering mode: the longest episode, in frames, a training window holds (the env's ``keyframe_budget`` + 1,
    the final observed state). Windows are ``-(L-1) .. L-1`` around any frame, so each holds its whole episode;
    every frame is sampled (no ``drop_n_last_frames``), which weights episodes by length."""
    memory_per_attempt: bool = False
    """Recovering mode: the LSTM state restarts from zero where the task goes back from place to pick (the
    re-pick after a drop or a displacement), so its memory spans one pick-and-place attempt. In training the
    restarts are where the per-frame ``phase.subtask`` labels switch back (the fast path, DAgger and stock
    ``lerobot-train`` on a dataset with the ``phase.*`` columns, ``stock_train``; without labels training stops
    with an error); at inference, where the subtask classifier switches back, and that step is re-run from the
    zero state. The paper's PICK and PLACE
    nets restart at their switch too. Why: with memory carried over the whole episode, an attempt's state
    depends on how many came before, and a third attempt (two displacements) is a history training never
    shows; with it, every later attempt starts as the trained re-picks do."""
    binary_gripper: bool = False
    """The post-processor snaps the gripper command to fully open or closed (threshold half way), as every
    demonstration commands it (``processor_pnp_lstm.BinaryGripperStep``). Off by default: the paper's planner
    regresses it."""
    subtask_loss_weight: float = 0.1
    """Recovering mode: weight of the cross-entropy of the subtask switch (``phase.subtask``) next to the action
    MSE. Used when the batch carries per-frame labels (the fast path and DAgger; stock ``lerobot-train`` windows
    only observations and actions, so there the switch learns from the action loss alone)."""
    phase_loss_weight: float = 0.1
    """Recovering mode: weight of the cross-entropy of the auxiliary phase classifier (``phase.index``) next to the
    action MSE. Used, like ``subtask_loss_weight``, only when the batch carries per-frame labels."""

    await_observation: bool = False
    """Recovering mode, inference only: hold a command that moves the arm or gripper, without stepping the network,
    until the observation shows the move (``observation_gate``), so that latency beyond the trained one is waited out."""
    await_state_tol: float = 0.35
    """With ``await_observation``: the normalised change of the observed robot state (Euclidean norm) that counts as
    "the move arrived": above the ``full`` task's observation noise, below nearly every keyframe move."""
    await_action_tol: float = 0.7
    """With ``await_observation``: a command that changes by more than this (normalised, Euclidean) is a move to wait
    for; twice ``await_state_tol``, so every move waited for is seen to arrive."""
    await_max_steps: int = 4
    """With ``await_observation``: the longest a command is held waiting for its move to be observed."""
    await_in_flight: int | None = None
    """With ``await_observation``: the moves that may be unobserved when the next one is planned (0: wait for each;
    None: the trained latency, ``latency_augment_max`` if ``latency_augment_prob > 0`` else 0)."""
    await_past_states: int = 2
    """With ``await_observation``: an observation equal to one of this many last observed states is the latency
    growing (the observation going back in time), not a new move."""

    still_arm_phases: list[int] = field(default_factory=list)
    """Recovering mode, inference only: the FSM states (``robot.Phase``) whose keyframe keeps the arm where the
    last one sent it. Where the phase classifier labels a keyframe with one of them, the planner repeats its last
    arm command and takes only the gripper from the network. Valid: the states the expert leaves without moving
    the arm (``STILL_ARM_PHASES``: the grasp's close 2, the hold before the place 4, the place's open 7, the hold
    after the retract 9). The recipe holds the place's open only: an open planned on an observation that misses
    the place descent otherwise carries an arm move that drags the object off the target (holding the close as
    well loses recoveries)."""
    still_arm_tol: float = 0.0
    """With ``still_arm_phases``: the arm is held only where the network's own keyframe would move it by more than
    this (Euclidean norm in normalised units, as ``await_action_tol``); a smaller move is kept. The network's open
    comes with a small refinement of the place pose when its view shows the descent, and with a large move when
    the view misses moves (observations older than trained); holding every open cost recoveries on the `paper`
    task under observation noise and large nudges, holding only the large moves does not (the recipe: 0.05).
    0 holds every keyframe so labelled."""

    balance_window_loss: bool = field(default=True, init=False, repr=False)
    """Retired, does nothing: neither a constructor argument nor a command-line option any more, only tolerated
    (and ignored) in the ``config.json`` / ``train_config.json`` of checkpoints written before every training window
    became a whole episode. It cannot be dropped from the dataclass: LeRobot decodes a checkpoint's config with
    draccus on the base class (``PreTrainedConfig.from_pretrained``, as ``lerobot-eval --policy.path`` does), which
    rejects an unknown key, and a draccus decoding hook would make the class unusable as a ``--policy.type`` choice."""

    def __post_init__(self) -> None:
        super().__post_init__()
        for ok, message in option_rules(self):
            if not ok:
                raise ConfigError(f"policy.{message}")

    # ---- task structure -------------------------------------------------------------------------

    @property
    def clock_frames(self) -> int:
        """Frames of the clocked planner's episode, one per FSM state (10 in the paper): ``n_subtasks *
        steps_per_subtask``. (The env's ``episode_length`` is its step budget, another quantity.)"""
        return self.n_subtasks * self.steps_per_subtask

    @property
    def recovering(self) -> bool:
        return self.mode == "recovering"

    @property
    def window_length(self) -> int:
        """Frames of the longest episode a training window holds: 10 clocked, ``max_episode_length`` recovering."""
        return self.max_episode_length if self.recovering else self.clock_frames

    @property
    def in_flight_moves(self) -> int:
        """``await_in_flight`` resolved: the moves the planner may run ahead of its observations."""
        if self.await_in_flight is not None:
            return self.await_in_flight
        return self.latency_augment_max if self.latency_augment_prob > 0 else 0

    def check_env_fps(self, env_fps: int | float | None) -> None:
        """Raise ``PolicyError`` when an env's control rate differs from the training dataset's.

        A keyframe checkpoint stepped at a dense control rate (or the reverse) gives 0 % success without any
        other symptom. Nothing is checked when either rate is unknown.
        """
        if self.dataset_fps is None or env_fps is None or int(env_fps) == int(self.dataset_fps):
            return
        raise PolicyError(
            f"this pnp_lstm checkpoint was trained on a {self.dataset_fps} fps dataset (one step per keyframe "
            f"when fps is 1), but the env runs at {env_fps} fps: evaluate it with the control mode of its training "
            "data (e.g. --env.control_mode keyframe)"
        )

    # ---- LeRobot contract -----------------------------------------------------------------------

    @property
    def observation_delta_indices(self) -> list[int]:
        # Every window holds its whole episode, wherever the sampled frame lies in it; LeRobot pads the frames
        # outside the episode (`<key>_is_pad`). With drop_n_last_frames the sampler picks frame 0 only.
        return list(range(-(self.window_length - 1), self.window_length))

    @property
    def action_delta_indices(self) -> list[int]:
        return self.observation_delta_indices

    @property
    def reward_delta_indices(self) -> None:
        return None

    @property
    def drop_n_last_frames(self) -> int:
        """Read by ``lerobot-train`` for its ``EpisodeAwareSampler``: clocked, sample each episode's first frame
        only; recovering (variable lengths), every frame (its window holds the whole episode too)."""
        return 0 if self.recovering else self.clock_frames - 1

    def get_optimizer_preset(self) -> AdamConfig:
        return AdamConfig(
            lr=self.optimizer_lr,
            weight_decay=self.optimizer_weight_decay,
            grad_clip_norm=self.optimizer_grad_clip_norm,
        )

    def get_scheduler_preset(self) -> LRSchedulerConfig | None:
        if self.lr_scheduler == "cosine":
            return CosineAnnealingWithWarmupSchedulerConfig(num_warmup_steps=self.scheduler_warmup_steps)
        return None

    def validate_features(self) -> None:
        """The planner needs the robot state, the object position and the action; no images."""
        inputs = self.input_features or {}
        outputs = self.output_features or {}
        state = inputs.get(OBS_STATE)
        if state is None or state.type is not FeatureType.STATE:
            raise ConfigError(
                f"pnp_lstm needs the input feature '{OBS_STATE}' (robot joints + gripper); "
                f"got input features {sorted(inputs)}"
            )
        env = inputs.get(OBS_ENV_STATE)
        if env is None or env.type is not FeatureType.ENV:
            raise ConfigError(
                f"pnp_lstm needs the input feature '{OBS_ENV_STATE}' (object position); "
                f"got input features {sorted(inputs)}"
            )
        if ACTION not in outputs:
            raise ConfigError(f"pnp_lstm needs the output feature '{ACTION}'; got {sorted(outputs)}")
        if self.image_features:
            logger.warning(
                "pnp_lstm is a state-only planner; it ignores the image features %s.", sorted(self.image_features)
            )
        for key, ft in {**inputs, **outputs}.items():
            if ft.type is FeatureType.VISUAL:
                continue
            if len(ft.shape) != 1:
                raise ConfigError(f"pnp_lstm expects 1-D features; '{key}' has shape {tuple(ft.shape)}")

    @property
    def model_input_keys(self) -> list[str]:
        """Input features fed to the LSTM, in concatenation order: state features first, then env."""
        inputs = self.input_features or {}
        keys = [k for k, ft in inputs.items() if ft.type in (FeatureType.STATE, FeatureType.ENV)]
        return sorted(keys, key=lambda k: (inputs[k].type is not FeatureType.STATE, k))
