"""``PnpLstmPolicy``: the data-driven task planner of de Magistris et al. 2016 as a LeRobot policy.

The split follows LeRobot's ``ACTPolicy`` / ``ACT``: ``PnpLstm`` (``clocked.py``) is the plain ``nn.Module``
(two LSTMs with a Linear head: the PICK net maps keyframes 0..4 to the next keyframe, the PLACE net, from a
zero hidden state, keyframes 5..9); ``PnpLstmPolicy`` wraps it with LeRobot's policy API (loss, per-episode
inference state, checkpoint loading). Inputs are the robot state (joints + gripper) and the object position,
normalised by the pre-processor, which is also the one place that checks observations; outputs are normalised
actions (next joint targets + gripper command) that the post-processor unnormalises.

Training batches (``forward``):
  * windows from ``lerobot-train``: every ``observation.*`` key and ``action`` arrive as ``(B, L, D)`` with
    ``<key>_is_pad`` masks; each window contains its whole episode (see the config), so the episode is
    the run of unpadded frames, taken out so that position ``k`` holds episode frame ``k``;
  * whole episodes from the fast path: ``(B, T, D)`` with no pad masks.

Inference (``select_action``): one ``(B, D)`` observation per environment step, every environment of the
batch at the same step (LeRobot resets the whole batch at once), so one scalar step counter does. Steps
``0..4`` run the PICK net, ``5..9`` the PLACE net (its hidden state zeroed at step 5); afterwards the policy
keeps returning the last action it predicted (the hold of the place-retract state). ``reset()`` clears it.

``--policy.mode=recovering`` replaces the clocked pair by ``recovering.RecoveringNet`` (no clock, one state
for the whole episode, a learned PICK/PLACE switch); the policy API, processors and checkpoints are the same.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F  # noqa: N812
from lerobot.policies.pretrained import PreTrainedPolicy
from lerobot.utils.constants import ACTION, OBS_STATE
from torch import Tensor, nn

from lerobot_pnp.errors import ConfigError, DatasetError, PolicyError

from .clocked import PnpLstm
from .configuration_pnp_lstm import PnpLstmConfig
from .observation_gate import ObservationGate
from .recovering import RecoveringNet, late_observer, recovering_loss

# Per-frame labels the recovering mode learns from when a batch carries them (fast path, DAgger).
SUBTASK_KEY = "phase.subtask"
PHASE_KEY = "phase.index"

logger = logging.getLogger(__name__)

# Checkpoints written before the network became its own module stored its weights at the policy's top level.
_LEGACY_PREFIX = "subtask_nets."


class TaskRecord:
    """How a checkpoint records the task it was trained in, set by ``lerobot_pnp.registration`` (the policy
    package knows no env): ``read(dataset_root)`` -> the validated recorded task or None, ``write(task,
    directory)`` writes it into a checkpoint folder."""

    read: Callable[[Path], dict | None] | None = None
    write: Callable[[dict, Path], None] | None = None


class PnpLstmPolicy(PreTrainedPolicy):
    """LeRobot policy around ``PnpLstm``. See the module docstring."""

    config_class = PnpLstmConfig
    name = "pnp_lstm"

    def __init__(self, config: PnpLstmConfig, dataset_stats: Any = None, dataset_meta: Any = None, **kwargs):
        super().__init__(config)
        config.validate_features()
        self.config: PnpLstmConfig = config
        if (
            config.torch_num_threads is not None
            and torch.device(config.device or "cpu").type == "cpu"
            and torch.get_num_threads() != config.torch_num_threads
        ):
            torch.set_num_threads(config.torch_num_threads)
        if dataset_meta is not None:
            _check_keyframe_episodes(
                dataset_meta, config.episode_length, exact=not config.recovering, max_length=config.window_length
            )
            config.dataset_fps = int(dataset_meta.fps)
        self.recorded_task = _recorded_task(dataset_meta)

        self.input_keys: list[str] = config.model_input_keys
        input_dim = sum(int(config.input_features[k].shape[0]) for k in self.input_keys)
        self.action_dim = int(config.output_features[ACTION].shape[0])
        if config.recovering:
            self.model = RecoveringNet(input_dim, config.hidden_size, self.action_dim, config.recurrent, config.dropout)
        else:
            self.model = PnpLstm(config, input_dim, self.action_dim)
        self.reset()

    @property
    def subtask_nets(self) -> nn.ModuleList:
        """The subtask networks (``model.subtask_nets``)."""
        return self.model.subtask_nets

    # ---- checkpoints ----------------------------------------------------------------------------

    def _save_pretrained(self, save_directory: Path, state_dict: dict[str, Tensor] | None = None) -> None:
        """LeRobot's save (``lerobot-train``'s checkpoints included), plus the task the policy was trained in
        (``baxter_pnp_env.json``, read when training started), so the checkpoint carries its task even after
        the dataset root is regenerated with another one."""
        super()._save_pretrained(save_directory, state_dict)
        if self.recorded_task is not None and TaskRecord.write is not None:
            TaskRecord.write(self.recorded_task, Path(save_directory))

    @classmethod
    def from_pretrained(cls, pretrained_name_or_path, *, config: PnpLstmConfig | None = None, **kwargs):
        """LeRobot's loader, with clear ``PolicyError``s for a missing, incomplete or unfitting checkpoint.

        ``make_policy`` replaces the checkpoint's output features with the env's (or dataset's); without the
        shape check a different action size surfaces as a bare state_dict size mismatch.
        """
        path = Path(str(pretrained_name_or_path)).expanduser()
        if path.exists() or _looks_like_a_path(str(pretrained_name_or_path)):
            if not path.is_dir():
                raise PolicyError(f"no pnp_lstm checkpoint at {path}: not a folder")
            missing = [f for f in ("config.json", "model.safetensors") if not (path / f).is_file()]
            if missing:
                raise PolicyError(
                    f"{path} is not a complete checkpoint folder (missing {', '.join(missing)}); pass a "
                    "checkpoint's pretrained_model folder, e.g. outputs/train/pnp_lstm/checkpoints/last/pretrained_model"
                )
            if config is not None:
                try:
                    saved = PnpLstmConfig.from_pretrained(path)
                except Exception as err:  # draccus / json errors of a corrupt config.json
                    raise PolicyError(f"cannot read the policy config {path / 'config.json'}: {err}") from None
                _check_same_shapes(path, config, saved)
        try:
            policy = super().from_pretrained(pretrained_name_or_path, config=config, **kwargs)
        except (ConfigError, OSError) as err:
            raise PolicyError(f"cannot load the pnp_lstm checkpoint {path}: {err}") from None
        from .weights import non_finite_weights

        bad = non_finite_weights(policy.state_dict())
        if bad:  # the checkpoint's fault, named here rather than as a NaN action steps later
            raise PolicyError(f"the pnp_lstm checkpoint {path} is corrupt: its weights {bad[:3]} contain NaN/inf")
        return policy

    @classmethod
    def _load_as_safetensor(cls, model, model_file: str, map_location: str, strict: bool):
        """Load the weights strictly (LeRobot's default is lenient), mapping the pre-``PnpLstm`` layout."""
        from safetensors import SafetensorError
        from safetensors.torch import load_file

        try:
            state = load_file(model_file, device=str(map_location or "cpu"))
        except (SafetensorError, OSError) as err:
            raise PolicyError(f"cannot read the weights {model_file}: {err}") from None
        state = {("model." + k if k.startswith(_LEGACY_PREFIX) else k): v for k, v in state.items()}
        try:
            model.load_state_dict(state, strict=True)
        except RuntimeError as err:
            first = str(err).strip().splitlines()
            raise PolicyError(
                f"the weights {model_file} do not fit this pnp_lstm config ({first[1].strip() if len(first) > 1 else first[0]})"
            ) from None
        return model

    # ---- LeRobot policy API ---------------------------------------------------------------------

    def get_optim_params(self) -> Any:
        return self.parameters()

    def reset(self) -> None:
        """Clear every per-episode cache: the step counter, the LSTM state and the held action."""
        self._step = 0
        self._state: tuple[Tensor, Tensor] | None = None
        self._last_action: Tensor | None = None
        cfg = self.config
        self._gate = (
            ObservationGate(
                int(cfg.input_features[OBS_STATE].shape[0]),
                cfg.await_state_tol,
                cfg.await_action_tol,
                cfg.await_max_steps,
                cfg.in_flight_moves,
                cfg.await_past_states,
            )
            if cfg.recovering and cfg.await_observation
            else None
        )

    def forward(self, batch: dict[str, Tensor], reduction: str = "mean") -> tuple[Tensor, dict]:
        """MSE between predicted and target normalised actions over each episode's frames.

        ``reduction="none"`` returns one loss per sample (LeRobot's sample-weighting hook).
        """
        if reduction not in ("mean", "none"):
            raise ConfigError(f"reduction must be 'mean' or 'none', got {reduction!r}")
        x = torch.cat([batch[k] for k in self.input_keys], dim=-1)
        y = batch[ACTION]
        labels = [batch.get(k) for k in (SUBTASK_KEY, PHASE_KEY)]
        labels = [v if _is_window(v, x) else None for v in labels]
        x, y, valid, labels = self._episodes_of(batch, x, y, labels)
        if self.training and self.config.latency_augment_prob > 0:
            cfg = self.config
            x, valid, src = late_observer(
                x, valid, cfg.latency_augment_prob, labels[1], cfg.latency_augment_max,
                cfg.latency_augment_jitter, cfg.latency_augment_stretch,
            )  # fmt: skip
            y = y.gather(1, src.unsqueeze(-1).expand(-1, -1, y.shape[-1]))
            labels = [None if v is None else v.gather(1, src) for v in labels]
        if self.training and self.config.input_noise_std > 0:
            x = x + self.config.input_noise_std * torch.randn_like(x)

        if self.config.recovering:
            cfg = self.config
            out = self.model(x)
            loss, per_sample, info = recovering_loss(
                out, y, valid, *labels, cfg.subtask_loss_weight, cfg.phase_loss_weight
            )
            return (per_sample, info) if reduction == "none" else (loss, info)

        pred = self.model(x)
        err = F.mse_loss(pred, y, reduction="none").mean(dim=-1)  # (B, T)
        validf = valid.to(err.dtype)
        per_sample = (err * validf).sum(dim=1) / validf.sum(dim=1).clamp(min=1.0)
        loss = (err * validf).sum() / validf.sum().clamp(min=1.0)

        info: dict[str, float] = {}
        with torch.no_grad():
            s = self.config.steps_per_subtask
            for sub, name in enumerate(_subtask_names(self.config.n_subtasks)):
                m = validf[:, sub * s : (sub + 1) * s]
                if m.numel() and float(m.sum()) > 0:
                    info[f"mse_{name}"] = float((err[:, sub * s : (sub + 1) * s] * m).sum() / m.sum())
        if reduction == "none":
            return per_sample, info
        return loss, info

    @torch.no_grad()
    def select_action(self, batch: dict[str, Tensor], **kwargs: Any) -> Tensor:
        """One normalised action per environment, ``(B, action_dim)``; advances the step counter."""
        cfg = self.config
        if cfg.recovering:
            return self._recovering_step(batch)
        step = self._step
        self._step = step + 1
        if step >= cfg.episode_length:
            if step == 4 * cfg.episode_length:
                _warn_long_episode(cfg, step)
            if self._last_action is not None and self._last_action.shape[0] != _batch_size(batch, self.input_keys):
                raise PolicyError(_BATCH_CHANGED)
            return self._last_action  # the hold of the last keyframe (read-only: a fresh tensor per episode)
        x = torch.cat([batch[k] for k in self.input_keys], dim=-1)
        state = self._state
        if state is not None and state[0].shape[1] != x.shape[0]:
            raise PolicyError(_BATCH_CHANGED)
        subtask, k = divmod(step, cfg.steps_per_subtask)
        if k == 0 and not (cfg.carry_hidden_across_subtasks and subtask > 0):
            state = None  # entering a subtask: its net starts from a zero hidden state (the paper)
        action, self._state = self.model.step(x, subtask, state)
        self._last_action = action
        return action

    def _recovering_step(self, batch: dict[str, Tensor]) -> Tensor:
        """No clock: one trunk step with the state carried since ``reset()``, until the env ends the episode."""
        x = torch.cat([batch[k] for k in self.input_keys], dim=-1)
        state = self._state
        if state is not None and state[0].shape[0] != x.shape[0]:
            raise PolicyError(_BATCH_CHANGED)
        out, new_state = self.model.step(x, state)
        self._step += 1
        action = out["action"]
        gate = self._gate
        if gate is not None:  # hold the last command where its move has not been observed yet
            decided = gate.decide(x)
            old = self._last_action
            if old is not None and not bool(decided.all()):
                action = torch.where(decided[:, None], action, old)
                if new_state is not None:
                    new_state = tuple(
                        torch.where(decided[:, None], n, o) for n, o in zip(new_state, state, strict=True)
                    )
            gate.update(decided, action, old)
            self._last_action = action
        self._state = new_state
        self.last_subtask_prob = out["subtask_logits"].softmax(dim=-1)[:, 1]  # P(place), for viewers / logs
        self.last_phase = out["phase_logits"].argmax(dim=-1)
        return action

    def predict_action_chunk(self, batch: dict[str, Tensor], **kwargs: Any) -> Tensor:
        """``select_action`` with a time dimension, ``(B, 1, action_dim)``. Advances the step counter."""
        return self.select_action(batch, **kwargs).unsqueeze(1)

    # ---- sequence model -------------------------------------------------------------------------

    def predict_sequence(self, batch: dict[str, Tensor]) -> Tensor:
        """Teacher-forced prediction for whole episodes: inputs ``(B, T, D)`` from frame 0 -> ``(B, T, A)``.

        Stateless (does not touch the inference state); used for evaluation on a dataset.
        """
        out = self.model(torch.cat([batch[k] for k in self.input_keys], dim=-1))
        return out["action"] if self.config.recovering else out

    def _episodes_of(
        self, batch: dict[str, Tensor], x: Tensor, y: Tensor, labels: list[Tensor | None] | None = None
    ) -> tuple[Tensor, Tensor, Tensor, list[Tensor | None]]:
        """Each sample's episode as ``(B, T, ·)`` from frame 0, and the mask of its real frames ``(B, T)``.

        A window's unpadded frames are its episode (the window covers the whole episode); the fast path's
        batches are whole episodes already.
        """
        t_ep = min(self.config.window_length, x.shape[1])
        labels = list(labels or [])
        pads = [batch[f"{k}_is_pad"] for k in (*self.input_keys, ACTION) if f"{k}_is_pad" in batch]
        if not pads:
            bsz, length = x.shape[:2]
            return x, y, torch.ones(bsz, length, dtype=torch.bool, device=x.device), labels
        pad = pads[0].to(device=x.device, dtype=torch.bool)
        real = ~pad
        n_real = real.sum(dim=1)
        first = real.to(torch.int8).argmax(dim=1)  # the episode's frame 0 (windows are contiguous)
        pos = torch.arange(t_ep, device=x.device)
        idx = (first.unsqueeze(1) + pos).clamp(max=x.shape[1] - 1)  # (B, T)
        x = x.gather(1, idx.unsqueeze(-1).expand(-1, -1, x.shape[-1]))
        y = y.gather(1, idx.unsqueeze(-1).expand(-1, -1, y.shape[-1]))
        labels = [None if v is None else v.to(x.device).gather(1, idx) for v in labels]
        return x, y, pos.unsqueeze(0) < n_real.unsqueeze(1), labels


def delay_some_episodes(x: Tensor, valid: Tensor, prob: float, phase: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """Episodes ``(B, T, D)`` from frame 0, each shown one step late with probability ``prob`` (frame ``t`` gets
    frame ``t-1``'s observation, frame 0 its own): ``recovering.late_observer`` with a lag of exactly 1."""
    x, valid, _ = late_observer(x, valid, prob, phase)
    return x, valid


_BATCH_CHANGED = (
    "the batch size changed within an episode; call policy.reset() when the environments are reset "
    "(LeRobot's rollout does)"
)


def _is_window(labels: Tensor | None, x: Tensor) -> bool:
    """Per-frame labels ``(B, L)`` aligned with the inputs (lerobot-train's batches carry one label per sample)."""
    return isinstance(labels, Tensor) and labels.ndim == 2 and tuple(labels.shape) == tuple(x.shape[:2])


def _batch_size(batch: dict[str, Tensor], keys: list[str]) -> int:
    return int(batch[keys[0]].shape[0])


def _warn_long_episode(cfg: PnpLstmConfig, step: int) -> None:
    logger.warning(
        "pnp_lstm was trained on keyframe episodes of %d steps (dataset fps %s) but has been stepped %d times "
        "since reset: is the env in another control mode (e.g. --env.control_mode dense)? It only holds its "
        "last keyframe from step %d on.",
        cfg.episode_length,
        cfg.dataset_fps if cfg.dataset_fps is not None else "unknown",
        step,
        cfg.episode_length,
    )


def _looks_like_a_path(name: str) -> bool:
    """A local path rather than a Hub repo id (``owner/name``)."""
    return name.startswith((".", "/", "~")) or name.count("/") > 1 or "\\" in name


def _check_same_shapes(path: Path, config: PnpLstmConfig, saved: PnpLstmConfig) -> None:
    for group in ("input_features", "output_features"):
        for key, ft in (getattr(config, group) or {}).items():
            saved_ft = (getattr(saved, group) or {}).get(key)
            if saved_ft is not None and tuple(saved_ft.shape) != tuple(ft.shape):
                raise PolicyError(
                    f"pnp_lstm checkpoint {path} was trained with {key} of shape {tuple(saved_ft.shape)}, "
                    f"but the env/dataset provides {tuple(ft.shape)}: it belongs to a different robot or task"
                )


def _subtask_names(n: int) -> list[str]:
    return ["pick", "place"] if n == 2 else [f"subtask{i}" for i in range(n)]


def _recorded_task(dataset_meta: Any) -> dict | None:
    """The task recorded with the training dataset (validated), None without a dataset or a record."""
    root = getattr(dataset_meta, "root", None)
    return None if root is None or TaskRecord.read is None else TaskRecord.read(Path(root))


def _check_keyframe_episodes(
    dataset_meta: Any, episode_length: int, exact: bool = True, max_length: int | None = None
) -> None:
    """Fail early (at policy construction in ``lerobot-train``) on a dataset that is not a keyframe dataset.

    Clocked: every episode has exactly ``episode_length`` frames. Recovering: at most ``max_length`` frames
    (a longer episode would not fit its training window)."""
    try:
        lengths = list(dataset_meta.episodes["length"])
    except (AttributeError, KeyError, TypeError):
        return
    if not exact:
        longer = sorted({int(n) for n in lengths if int(n) > int(max_length or 0)})
        if longer:
            raise DatasetError(
                f"episodes of {longer[:5]} frames do not fit policy.max_episode_length={max_length}: "
                f"raise it to at least {longer[-1]}"
            )
        return
    bad = sorted({int(n) for n in lengths if int(n) != episode_length})
    if bad:
        raise DatasetError(
            f"not a keyframe dataset: pnp_lstm needs every episode to have exactly {episode_length} frames "
            f"(one per FSM state), found episode lengths {bad[:10]}; a dataset with recoveries (the `full` task) "
            "trains with --policy.mode=recovering"
        )
