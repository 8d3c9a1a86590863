"""``PnpPixelsPolicy``: the recovering planner on joint state + camera images (``configuration_pnp_pixels``).

It is ``PnpLstmPolicy`` with a keypoint encoder in front (``image_encoder.KeypointEncoder``, one per camera): each
frame's images become ``2 * num_keypoints`` image coordinates per camera (and, with ``keypoint_strength``,
``num_keypoints`` feature values), put into the batch as
``observation.image_keypoints`` and concatenated after the joint state, the planner's whole input. The planner,
its losses, windows, augmentation, inference state and checkpoints are the state planner's, unchanged.

Only real frames are encoded: a ``lerobot-train`` window holds its whole episode padded to twice the longest one,
and the fast path pads episodes to the longest; padded frames get zero keypoints (they are out of every loss).
"""

from __future__ import annotations

from typing import Any

import torch
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_STATE
from torch import Tensor, nn

from .configuration_pnp_pixels import PnpPixelsConfig
from .image_encoder import KeypointEncoder
from .modeling_pnp_lstm import PnpLstmPolicy

KEYPOINTS_KEY = "observation.image_keypoints"  # computed in the batch, never a dataset or env feature


class PnpPixelsPolicy(PnpLstmPolicy):
    """LeRobot policy: image encoder + the recovering planner (see the module docstring)."""

    config_class = PnpPixelsConfig
    name = "pnp_pixels"

    def _planner_inputs(self, config: PnpPixelsConfig) -> tuple[list[str], int]:
        """Build the encoders (one per camera) and the auxiliary pose head; the planner reads the joint state and
        the keypoints."""
        self.camera_keys = config.camera_keys
        shape = tuple(int(n) for n in config.image_features[self.camera_keys[0]].shape)
        self.encoders = nn.ModuleList(
            KeypointEncoder(
                shape,
                list(config.conv_channels),
                config.num_keypoints,
                config.image_shift,
                config.image_downsample,
                config.keypoint_strength,
                config.keypoint_strength_norm,
            )
            for _ in self.camera_keys
        )
        width = sum(enc.out_dim for enc in self.encoders)
        env = (config.input_features or {}).get(OBS_ENV_STATE)
        self.pose_head = None
        if env is not None and config.pose_loss_weight > 0:  # training-time target only
            self.pose_head = nn.Sequential(nn.Linear(width, 64), nn.ReLU(), nn.Linear(64, int(env.shape[0])))
        keys = config.model_input_keys
        return [*keys, KEYPOINTS_KEY], sum(int(config.input_features[k].shape[0]) for k in keys) + width

    # ---- the image keypoints in the batch ------------------------------------------------------

    def keypoints(self, batch: dict[str, Tensor]) -> tuple[Tensor, Tensor]:
        """Each frame's keypoints ``(..., F)`` (zeros where padded) and the mask of the real frames ``(...)``."""
        first = batch[self.camera_keys[0]]
        lead = first.shape[:-3]
        real = torch.ones(lead, dtype=torch.bool, device=first.device)
        for key in (f"{self.camera_keys[0]}_is_pad", f"{OBS_STATE}_is_pad", f"{ACTION}_is_pad"):
            pad = batch.get(key)
            if isinstance(pad, Tensor) and tuple(pad.shape) == tuple(lead):
                real = ~pad.to(device=first.device, dtype=torch.bool)
                break
        feats = torch.cat([enc(batch[k][real]) for k, enc in zip(self.camera_keys, self.encoders, strict=True)], -1)
        out = feats.new_zeros(*lead, feats.shape[-1])
        out[real] = feats
        return out, real

    def _with_keypoints(self, batch: dict[str, Tensor]) -> tuple[dict[str, Tensor], Tensor, Tensor]:
        feats, real = self.keypoints(batch)
        return {**batch, KEYPOINTS_KEY: feats}, feats, real

    # ---- LeRobot policy API ---------------------------------------------------------------------

    def forward(self, batch: dict[str, Tensor], reduction: str = "mean") -> tuple[Tensor, dict]:
        """The state planner's loss on joints + keypoints, plus (``pose_loss_weight``, where the batch records the
        environment state) the auxiliary MSE of that state predicted from the keypoints."""
        batch, feats, real = self._with_keypoints(batch)
        loss, info = super().forward(batch, reduction)
        target = batch.get(OBS_ENV_STATE)
        if self.pose_head is not None and isinstance(target, Tensor) and target.shape[:-1] == real.shape:
            err = ((self.pose_head(feats) - target) ** 2).mean(dim=-1) * real
            per_sample = err.reshape(err.shape[0], -1).sum(1) / real.reshape(real.shape[0], -1).sum(1).clamp(min=1)
            pose = err.sum() / real.sum().clamp(min=1)
            weight = self.config.pose_loss_weight
            loss = loss + weight * (per_sample if reduction == "none" else pose)
            info = {**info, "pose_loss": float(pose.detach())}
        return loss, info

    @torch.no_grad()
    def select_action(self, batch: dict[str, Tensor], **kwargs: Any) -> Tensor:
        """One normalised action per environment from its joints and images (the environment state, if the
        batch carries one, is not read)."""
        return super().select_action(self._with_keypoints(batch)[0], **kwargs)

    def predict_sequence(self, batch: dict[str, Tensor]) -> Tensor:
        return super().predict_sequence(self._with_keypoints(batch)[0])
