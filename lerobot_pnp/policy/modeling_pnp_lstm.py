"""``PnpLstmPolicy``: the data-driven task planner of de Magistris et al. 2016 as a LeRobot policy.

The split follows LeRobot's ``ACTPolicy`` / ``ACT``: the planner (``policy.model``, an ``nn.Module`` with all
the weights) is ``ClockedPlanner`` (the paper's two LSTMs on a fixed clock, the default) or
``RecoveringPlanner`` (no clock, a learned PICK/PLACE switch), both behind the one interface
``planner.Planner``; ``modes.build_planner`` picks it from the config. ``PnpLstmPolicy`` wraps it with
LeRobot's policy API (batches, augmentation, the per-episode inference state, checkpoint loading) and never asks
which planner it has. Inputs are the robot state (joints + gripper) and the object position, normalised by the
pre-processor, which is also the one place that checks observations; outputs are normalised actions (next
joint targets + gripper command) that the post-processor unnormalises.

Training batches (``forward``):
  * windows from ``lerobot-train``: every ``observation.*`` key and ``action`` arrive as ``(B, L, D)`` with
    ``<key>_is_pad`` masks; each window contains its whole episode (see the config), so the episode is
    the run of unpadded frames, taken out so that position ``k`` holds episode frame ``k``;
  * whole episodes from the fast path: ``(B, T, D)`` with no pad masks.

Inference (``select_action``): one ``(B, D)`` observation per environment step, every environment of the
batch at the same step (LeRobot resets the whole batch at once), so one ``planner.PlannerState`` (a scalar
step count, the last action, the network's memory) does; ``reset()`` clears it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
from lerobot.policies.pretrained import PreTrainedPolicy
from lerobot.utils.constants import ACTION
from torch import Tensor, nn

from lerobot_pnp.errors import ConfigError, PolicyError

from . import processor_pnp_lstm  # noqa: F401  (registers the processor steps a saved pnp_lstm pipeline names)
from .configuration_pnp_lstm import PnpLstmConfig
from .latency import late_observer
from .modes import build_planner
from .planner import PlannerState

# Per-frame labels (FSM subtask and phase) a planner may learn from when a batch carries them (fast path, DAgger).
SUBTASK_KEY = "phase.subtask"
PHASE_KEY = "phase.index"

# Checkpoints written before the network became its own module stored its weights at the policy's top level.
_LEGACY_PREFIX = "subtask_nets."


class TaskRecord:
    """How a checkpoint records the task it was trained in, set by ``lerobot_pnp.integration.registration`` (the policy
    package knows no env): ``read(dataset_root)`` -> the validated recorded task or None, ``write(task,
    directory)`` writes it into a checkpoint folder."""

    read: Callable[[Path], dict | None] | None = None
    write: Callable[[dict, Path], None] | None = None


class PnpLstmPolicy(PreTrainedPolicy):
    """LeRobot policy around a planner (``policy.model``). See the module docstring."""

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
        self.input_keys, input_dim = self._planner_inputs(config)
        self.action_dim = int(config.output_features[ACTION].shape[0])
        self.model = build_planner(config, input_dim, self.action_dim)
        if dataset_meta is not None:
            lengths = _episode_lengths(dataset_meta)
            if lengths is not None:  # fail early (at construction in lerobot-train) on data it cannot learn
                self.model.check_episode_lengths(lengths)
            config.dataset_fps = int(dataset_meta.fps)
        self.recorded_task = _recorded_task(dataset_meta)
        self.reset()

    def _planner_inputs(self, config: PnpLstmConfig) -> tuple[list[str], int]:
        """The batch keys concatenated, in order, into the planner's input, and its width (``pnp_pixels`` adds the
        image keypoints it computes into the batch)."""
        keys = config.model_input_keys
        return keys, sum(int(config.input_features[k].shape[0]) for k in keys)

    @property
    def subtask_nets(self) -> nn.ModuleList:
        """The clocked planner's subtask networks (``model.subtask_nets``)."""
        return self.model.subtask_nets

    @property
    def last_subtask_prob(self) -> Tensor | None:
        """``(B,)`` P(place) at the last step of a planner with a learned switch, for viewers and logs; else None."""
        return None if self._state is None else self._state.subtask_prob

    @property
    def last_phase(self) -> Tensor | None:
        """``(B,)`` the FSM phase a planner with a phase classifier predicted at the last step (diagnostics); else None."""
        return None if self._state is None else self._state.phase

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
        """Load the weights strictly (LeRobot's default is lenient), mapping the pre-``model.`` layout."""
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
        """Clear the per-episode inference state (step count, network memory, held action, observation gate)."""
        self._state: PlannerState | None = None

    def forward(self, batch: dict[str, Tensor], reduction: str = "mean") -> tuple[Tensor, dict]:
        """The planner's loss over each episode's real frames (the MSE between predicted and target normalised
        actions, plus the terms of a planner's classifiers), after the training-time augmentation.

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

        loss, per_sample, info = self.model.loss(x, y, valid, *labels)
        return (per_sample, info) if reduction == "none" else (loss, info)

    @torch.no_grad()
    def select_action(self, batch: dict[str, Tensor], **kwargs: Any) -> Tensor:
        """One normalised action per environment, ``(B, action_dim)``; advances the planner's state."""
        x = torch.cat([batch[k] for k in self.input_keys], dim=-1)
        if self._state is not None and self._state.batch_size != x.shape[0]:
            raise PolicyError(_BATCH_CHANGED)
        action, self._state = self.model.act(x, self._state)
        return action

    def predict_action_chunk(self, batch: dict[str, Tensor], **kwargs: Any) -> Tensor:
        """``select_action`` with a time dimension, ``(B, 1, action_dim)``. Advances the planner's state."""
        return self.select_action(batch, **kwargs).unsqueeze(1)

    # ---- sequence model -------------------------------------------------------------------------

    def predict_sequence(self, batch: dict[str, Tensor]) -> Tensor:
        """Teacher-forced prediction for whole episodes: inputs ``(B, T, D)`` from frame 0 -> ``(B, T, A)``.

        Stateless (does not touch the inference state); used for evaluation on a dataset. A recovering planner
        with ``memory_per_attempt`` restarts its memory at the batch's ``phase.subtask`` switches, where it has them.
        """
        x = torch.cat([batch[k] for k in self.input_keys], dim=-1)
        subtask = batch.get(SUBTASK_KEY)
        if self.config.recovering and _is_window(subtask, x):
            return self.model.sequence(x, subtask)
        return self.model.sequence(x)

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
    frame ``t-1``'s observation, frame 0 its own): ``latency.late_observer`` with a lag of exactly 1."""
    x, valid, _ = late_observer(x, valid, prob, phase)
    return x, valid


_BATCH_CHANGED = (
    "the batch size changed within an episode; call policy.reset() when the environments are reset "
    "(LeRobot's rollout does)"
)


def _is_window(labels: Tensor | None, x: Tensor) -> bool:
    """Per-frame labels ``(B, L)`` aligned with the inputs (lerobot-train's batches carry one label per sample)."""
    return isinstance(labels, Tensor) and labels.ndim == 2 and tuple(labels.shape) == tuple(x.shape[:2])


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


def _recorded_task(dataset_meta: Any) -> dict | None:
    """The task recorded with the training dataset (validated), None without a dataset or a record."""
    root = getattr(dataset_meta, "root", None)
    return None if root is None or TaskRecord.read is None else TaskRecord.read(Path(root))


def _episode_lengths(dataset_meta: Any) -> list[int] | None:
    """The episode lengths of a training dataset's metadata, None where it has none (a stand-in in tests)."""
    try:
        return [int(n) for n in dataset_meta.episodes["length"]]
    except (AttributeError, KeyError, TypeError):
        return None
