"""``PnpLstmPolicy``: the data-driven task planner of de Magistris et al. 2016 as a LeRobot policy.

Two LSTMs with the same architecture (LSTM + Linear head): the PICK net maps keyframes 0..4 to the next
keyframe, the PLACE net (starting from a zero hidden state) maps keyframes 5..9. Inputs are the robot state
(joints + gripper) and the object position, normalised by the pre-processor; outputs are normalised
actions (next joint targets + gripper command) that the post-processor unnormalises.

Training batches (``forward``):
  * windowed, from ``lerobot-train``: every ``observation.*`` key and ``action`` arrive as ``(B, T, D)``
    with ``T = episode_length`` and ``<key>_is_pad`` masks. The window ends at the sampled frame, so the
    pads are a prefix; each sequence is shifted left so that position ``k`` holds episode frame ``k``.
  * whole episodes, from the fast path: ``(B, T, D)`` with no pad masks (all frames valid, frame = position).

Inference (``select_action``): one ``(B, D)`` observation per environment step. The policy keeps, per
environment, a step counter and the LSTM state; steps ``0..4`` run the PICK net, steps ``5..9`` the PLACE
net (its hidden state is zeroed at step 5). After the last keyframe step the policy keeps returning the
last action it predicted (the hold of the place-retract state). ``reset()`` clears all of it.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F  # noqa: N812
from lerobot.policies.pretrained import PreTrainedPolicy
from lerobot.utils.constants import ACTION, OBS_PREFIX
from torch import Tensor, nn

from .configuration_pnp_lstm import PnpLstmConfig

logger = logging.getLogger(__name__)


class SubtaskLSTM(nn.Module):
    """One subtask network: LSTM (batch first) followed by a Linear head on every step's output."""

    def __init__(self, input_dim: int, hidden_size: int, num_layers: int, dropout: float, output_dim: int):
        super().__init__()
        self.lstm = nn.LSTM(
            input_size=input_dim,
            hidden_size=hidden_size,
            num_layers=num_layers,
            batch_first=True,
            dropout=dropout if num_layers > 1 else 0.0,
        )
        self.dropout = nn.Dropout(dropout)
        self.head = nn.Linear(hidden_size, output_dim)

    def forward(self, x: Tensor, state: tuple[Tensor, Tensor] | None = None) -> tuple[Tensor, tuple[Tensor, Tensor]]:
        out, state = self.lstm(x, state)
        return self.head(self.dropout(out)), state


class PnpLstmPolicy(PreTrainedPolicy):
    """LSTM task planner (one network per subtask by default). See the module docstring."""

    config_class = PnpLstmConfig
    name = "pnp_lstm"

    @classmethod
    def from_pretrained(cls, pretrained_name_or_path, *, config: PnpLstmConfig | None = None, **kwargs):
        """LeRobot's loader, plus a clear error when the caller's features do not fit the checkpoint.

        ``make_policy`` replaces the checkpoint's output features with the env's (or dataset's); without this
        check a different action size surfaces as a bare state_dict size mismatch.
        """
        path = Path(str(pretrained_name_or_path))
        if config is not None and (path / "config.json").is_file():
            saved = PnpLstmConfig.from_pretrained(path)
            for group in ("input_features", "output_features"):
                for key, ft in (getattr(config, group) or {}).items():
                    saved_ft = (getattr(saved, group) or {}).get(key)
                    if saved_ft is not None and tuple(saved_ft.shape) != tuple(ft.shape):
                        raise ValueError(
                            f"pnp_lstm checkpoint {path} was trained with {key} of shape {tuple(saved_ft.shape)}, "
                            f"but the env/dataset provides {tuple(ft.shape)}: it belongs to a different robot or task"
                        )
        return super().from_pretrained(pretrained_name_or_path, config=config, **kwargs)

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
            _check_keyframe_episodes(dataset_meta, config.episode_length)

        self.input_keys: list[str] = config.model_input_keys
        self.input_dims: list[int] = [int(config.input_features[k].shape[0]) for k in self.input_keys]
        self.action_dim = int(config.output_features[ACTION].shape[0])
        extra = config.n_subtasks if config.shared_network else 0
        n_nets = 1 if config.shared_network else config.n_subtasks
        self.subtask_nets = nn.ModuleList(
            SubtaskLSTM(
                input_dim=sum(self.input_dims) + extra,
                hidden_size=config.hidden_size,
                num_layers=config.num_layers,
                dropout=config.dropout,
                output_dim=self.action_dim,
            )
            for _ in range(n_nets)
        )
        self.reset()

    # ---- LeRobot policy API ---------------------------------------------------------------------

    def get_optim_params(self) -> Any:
        return self.parameters()

    def reset(self) -> None:
        """Clear every per-episode cache: step counters, LSTM states and the held action."""
        self._step: Tensor | None = None
        self._hidden: tuple[Tensor, Tensor] | None = None
        self._last_action: Tensor | None = None

    def forward(self, batch: dict[str, Tensor], reduction: str = "mean") -> tuple[Tensor, dict]:
        """Masked MSE between predicted and target normalised actions over the valid frames.

        ``reduction="none"`` returns one loss per sample (LeRobot's sample-weighting hook).
        """
        if reduction not in ("mean", "none"):
            raise ValueError(f"reduction must be 'mean' or 'none', got {reduction!r}.")
        x = self._gather_inputs(batch, sequence=True)
        y = self._get_action_target(batch, x.shape[:2])
        bsz, length = x.shape[:2]
        t_ep = self.config.episode_length

        pad = self._get_pad_mask(batch, bsz, length)
        windowed = pad is not None
        if windowed:
            n_pad = pad.sum(dim=1)
            if bool((n_pad >= length).any()):
                raise ValueError("A training window has no valid frame (all padded).")
            pos = torch.arange(length, device=x.device)
            idx = (pos.unsqueeze(0) + n_pad.unsqueeze(1)).clamp(max=length - 1)  # (B, T)
            x = x.gather(1, idx.unsqueeze(-1).expand(-1, -1, x.shape[-1]))
            y = y.gather(1, idx.unsqueeze(-1).expand(-1, -1, y.shape[-1]))
            valid = pos.unsqueeze(0) < (length - n_pad).unsqueeze(1)
        else:
            valid = torch.ones(bsz, length, dtype=torch.bool, device=x.device)

        if self.training and self.config.input_noise_std > 0:
            x = x + self.config.input_noise_std * torch.randn_like(x)

        pred = self._run_sequence(x)
        err = F.mse_loss(pred, y, reduction="none").mean(dim=-1)  # (B, T)
        validf = valid.to(err.dtype)

        if windowed and self.config.balance_window_loss:
            k = torch.arange(length, device=x.device, dtype=err.dtype)
            weight = t_ep / (t_ep - k)  # 1 / P(frame k is in a window ending at a uniform frame)
            per_sample = (err * validf * weight).sum(dim=1) / t_ep
            loss = per_sample.mean()
        else:
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
        """One normalised action per environment, ``(B, action_dim)``; advances the step counters."""
        x = self._gather_inputs(batch, sequence=False)  # (B, D_in)
        bsz = x.shape[0]
        cfg = self.config
        if self._step is None:
            self._init_inference_state(bsz, x.device, x.dtype)
        elif self._step.shape[0] != bsz:
            raise ValueError(
                f"Batch size changed from {self._step.shape[0]} to {bsz} within an episode; "
                "call policy.reset() when the environments are reset."
            )
        assert self._step is not None and self._hidden is not None and self._last_action is not None

        # All updates are out of place, so the caches work with and without torch.inference_mode().
        step = self._step
        action = self._last_action  # rows past the last keyframe keep holding their last action
        active = step < cfg.episode_length
        subtask = torch.div(step, cfg.steps_per_subtask, rounding_mode="floor")
        h, c = self._hidden
        for sub in torch.unique(subtask[active]).tolist():
            rows = active & (subtask == sub)
            idx = rows.nonzero(as_tuple=True)[0]
            # Entering a subtask: its network starts from a zero hidden state (paper: the place net is
            # run from scratch on the pick-retract state), unless the shared net carries it over.
            if not (cfg.carry_hidden_across_subtasks and sub > 0):
                starting = (rows & (step == sub * cfg.steps_per_subtask)).view(1, -1, 1)
                h = torch.where(starting, torch.zeros_like(h), h)
                c = torch.where(starting, torch.zeros_like(c), c)
            state = (h.index_select(1, idx), c.index_select(1, idx)) if cfg.recurrent else None
            y, new_state = self._apply_net(sub, x.index_select(0, idx).unsqueeze(1), state)
            if new_state is not None:
                h = h.index_copy(1, idx, new_state[0])
                c = c.index_copy(1, idx, new_state[1])
            action = action.index_copy(0, idx, y[:, 0])
        self._hidden = (h, c)
        self._last_action = action
        self._step = step + 1
        return action

    def predict_action_chunk(self, batch: dict[str, Tensor], **kwargs: Any) -> Tensor:
        """``select_action`` with a time dimension, ``(B, 1, action_dim)``. Advances the step counters."""
        return self.select_action(batch, **kwargs).unsqueeze(1)

    # ---- sequence model -------------------------------------------------------------------------

    def predict_sequence(self, batch: dict[str, Tensor]) -> Tensor:
        """Teacher-forced prediction for whole episodes: inputs ``(B, T, D)`` from frame 0 -> ``(B, T, A)``.

        Stateless (does not touch the inference caches); used for evaluation on a dataset.
        """
        x = self._gather_inputs(batch, sequence=True)
        return self._run_sequence(x)

    def _run_sequence(self, x: Tensor) -> Tensor:
        """Run the subtask networks over ``x`` whose position ``k`` is episode frame ``k``."""
        s = self.config.steps_per_subtask
        outs: list[Tensor] = []
        state = None
        for sub in range(self.config.n_subtasks):
            seg = x[:, sub * s : (sub + 1) * s]
            if seg.shape[1] == 0:
                break
            if not self.config.carry_hidden_across_subtasks:
                state = None
            y, state = self._apply_net(sub, seg, state)
            outs.append(y)
        return torch.cat(outs, dim=1)

    def _apply_net(
        self, subtask: int, x: Tensor, state: tuple[Tensor, Tensor] | None
    ) -> tuple[Tensor, tuple[Tensor, Tensor] | None]:
        """Apply the network of ``subtask`` to ``x`` of shape ``(B, t, D_in)``."""
        cfg = self.config
        net = self.subtask_nets[0 if cfg.shared_network else subtask]
        bsz, t, _ = x.shape
        if cfg.shared_network:
            onehot = torch.zeros(bsz, t, cfg.n_subtasks, dtype=x.dtype, device=x.device)
            onehot[..., subtask] = 1.0
            x = torch.cat([x, onehot], dim=-1)
        if cfg.recurrent:
            return net(x, state)
        # Memoryless ablation: same layers, hidden state reset to zero before every step.
        y, _ = net(x.reshape(bsz * t, 1, x.shape[-1]), None)
        return y.reshape(bsz, t, -1), None

    def _init_inference_state(self, bsz: int, device: torch.device, dtype: torch.dtype) -> None:
        cfg = self.config
        self._step = torch.zeros(bsz, dtype=torch.long, device=device)
        shape = (cfg.num_layers, bsz, cfg.hidden_size)
        self._hidden = (torch.zeros(shape, dtype=dtype, device=device), torch.zeros(shape, dtype=dtype, device=device))
        self._last_action = torch.zeros(bsz, self.action_dim, dtype=dtype, device=device)

    # ---- batch checking -------------------------------------------------------------------------

    def _gather_inputs(self, batch: dict[str, Tensor], *, sequence: bool) -> Tensor:
        """Concatenate the model inputs, checking presence, shape and finiteness of every feature.

        ``sequence=True``: each feature is ``(B, T, D)``; otherwise ``(B, D)`` (or ``(D,)``, taken as B=1).
        """
        parts: list[Tensor] = []
        lead_shape: tuple[int, ...] | None = None
        ref_param = next(self.parameters())
        for key, dim in zip(self.input_keys, self.input_dims, strict=True):
            if key not in batch:
                present = sorted(k for k in batch if k.startswith(OBS_PREFIX))
                raise ValueError(
                    f"Input feature '{key}' (shape ({dim},)) is missing from the batch; "
                    f"observation keys present: {present}."
                )
            t = batch[key]
            if not isinstance(t, Tensor):
                t = torch.as_tensor(t)
            if not sequence and t.ndim == 1:
                t = t.unsqueeze(0)
            want_ndim = 3 if sequence else 2
            if t.ndim != want_ndim or t.shape[-1] != dim:
                layout = "(B, T, D)" if sequence else "(B, D)"
                raise ValueError(
                    f"Input feature '{key}' has shape {tuple(t.shape)}; expected {layout} with D={dim} "
                    f"(config.input_features['{key}'].shape = ({dim},))."
                )
            if lead_shape is None:
                lead_shape = tuple(t.shape[:-1])
            elif tuple(t.shape[:-1]) != lead_shape:
                raise ValueError(
                    f"Input feature '{key}' has leading shape {tuple(t.shape[:-1])}, other inputs have {lead_shape}."
                )
            if not bool(torch.isfinite(t).all()):
                raise ValueError(f"Input feature '{key}' contains non-finite values (NaN or inf).")
            parts.append(t.to(device=ref_param.device, dtype=ref_param.dtype))
        x = torch.cat(parts, dim=-1)
        if sequence and x.shape[1] > self.config.episode_length:
            raise ValueError(
                f"Sequences of {x.shape[1]} frames are longer than an episode of the task "
                f"({self.config.episode_length} = {self.config.n_subtasks} x {self.config.steps_per_subtask}); "
                "pnp_lstm trains on a keyframe dataset."
            )
        return x

    def _get_action_target(self, batch: dict[str, Tensor], lead_shape: tuple[int, ...]) -> Tensor:
        if ACTION not in batch:
            raise ValueError(f"Training batch has no '{ACTION}' key.")
        y = batch[ACTION]
        if y.ndim != 3 or tuple(y.shape[:2]) != tuple(lead_shape) or y.shape[-1] != self.action_dim:
            raise ValueError(
                f"'{ACTION}' has shape {tuple(y.shape)}; "
                f"expected ({lead_shape[0]}, {lead_shape[1]}, {self.action_dim})."
            )
        if not bool(torch.isfinite(y).all()):
            raise ValueError(f"'{ACTION}' contains non-finite values (NaN or inf).")
        ref = next(self.parameters())
        return y.to(device=ref.device, dtype=ref.dtype)

    def _get_pad_mask(self, batch: dict[str, Tensor], bsz: int, length: int) -> Tensor | None:
        """The window's pad mask ``(B, T)`` (True = frame outside the episode), or None for full episodes."""
        masks = {
            k: batch[f"{k}_is_pad"]
            for k in (*self.input_keys, ACTION)
            if f"{k}_is_pad" in batch and isinstance(batch[f"{k}_is_pad"], Tensor)
        }
        if not masks:
            return None
        pad: Tensor | None = None
        for key, m in masks.items():
            m = m.to(torch.bool)
            if tuple(m.shape) != (bsz, length):
                raise ValueError(f"'{key}_is_pad' has shape {tuple(m.shape)}; expected ({bsz}, {length}).")
            if pad is None:
                pad = m
            elif not torch.equal(pad, m):
                raise ValueError(
                    "Pad masks of the inputs and the action differ; observation and action windows must use "
                    "the same delta indices."
                )
        assert pad is not None
        pad = pad.to(self.subtask_nets[0].head.weight.device)
        # Windows end at the sampled frame, so padding (frames before the episode start) is a prefix.
        if length > 1 and bool((pad[:, 1:] & ~pad[:, :-1]).any()):
            raise ValueError(
                "Padding inside or at the end of a window: pnp_lstm expects windows that end at the sampled frame "
                "(observation/action delta indices -(T-1)..0)."
            )
        return pad


def _subtask_names(n: int) -> list[str]:
    return ["pick", "place"] if n == 2 else [f"subtask{i}" for i in range(n)]


def _check_keyframe_episodes(dataset_meta: Any, episode_length: int) -> None:
    """Fail early (at policy construction in ``lerobot-train``) on a dataset that is not a keyframe dataset."""
    try:
        lengths = list(dataset_meta.episodes["length"])
    except Exception:
        return
    bad = sorted({int(n) for n in lengths if int(n) != episode_length})
    if bad:
        raise ValueError(
            f"Not a keyframe dataset: pnp_lstm needs every episode to have exactly {episode_length} frames "
            f"(one per FSM state), found episode lengths {bad[:10]}."
        )
