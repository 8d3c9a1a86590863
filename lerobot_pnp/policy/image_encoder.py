"""A compact image encoder for the camera planner: a shallow conv net and a spatial-softmax keypoint head.

Finn et al. 2016 ("Deep Spatial Autoencoders for Visuomotor Learning") and robomimic's ``ShallowConv`` +
``SpatialSoftmax``: a few strided convolutions, then one feature map per keypoint whose softmax over the image
gives an expected (x, y) position. The output is ``2 * num_keypoints`` numbers in [-1, 1] per camera: where in
the image the things that matter are (the cube, the target, the gripper), which is what a planner that otherwise
reads the cube's coordinates needs, at a small fraction of a ResNet's cost on a CPU.

The encoder may read each image average-pooled (``pool``): the resolution it sees is then a choice of the
policy, measured against success, apart from the resolution the benchmark renders and records.

Training-time augmentation: a random shift of up to ``shift`` pixels per image (DrQ's pad-and-crop, as
robomimic's crop randomiser), so that a few hundred demonstrations do not teach exact pixel positions.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn


class SpatialSoftmax(nn.Module):
    """``(N, K, H, W)`` feature maps -> ``(N, 2K)`` expected (x, y) of each map's softmax, in [-1, 1].

    The temperature is learned (robomimic's ``learnable_temperature``): sharp maps localise, soft ones average.
    ``strength`` also gives each map's value where its softmax looks (``(N, K)``)."""

    def __init__(self, height: int, width: int):
        super().__init__()
        ys, xs = torch.meshgrid(torch.linspace(-1, 1, height), torch.linspace(-1, 1, width), indexing="ij")
        self.register_buffer("grid", torch.stack([xs.reshape(-1), ys.reshape(-1)], dim=1), persistent=False)
        self.log_temperature = nn.Parameter(torch.zeros(()))

    def forward(self, maps: Tensor) -> Tensor:
        return self.attend(maps)[0]

    def attend(self, maps: Tensor) -> tuple[Tensor, Tensor]:
        """The expected positions ``(N, 2K)`` and the attention-weighted map values ``(N, K)``."""
        n, k = maps.shape[:2]
        flat = maps.reshape(n, k, -1)
        attention = torch.softmax(flat / self.log_temperature.exp(), dim=-1)
        return (attention @ self.grid).reshape(n, 2 * k), (attention * flat).sum(-1)


class KeypointEncoder(nn.Module):
    """One camera's images ``(N, 3, H, W)`` (float in [0, 1], or uint8) -> keypoints ``(N, 2 * num_keypoints)``,
    followed, with ``strength``, by each keypoint's map value where it is attended (``(N, 3 * num_keypoints)``).

    ``channels``: the conv layers before the keypoint maps, the first 5x5 and the rest 3x3, each with stride 2;
    the keypoint maps are a 3x3 conv on the last layer's resolution.

    Why ``strength``: a keypoint is where a feature fires, not how strongly. The cube looks the same every 90
    degrees, so an orientation-tuned feature fires around its centre at every yaw and its expected position
    carries little of the yaw; how strongly it fires there carries it.

    ``strength_norm``: the strengths pass through a batch normalisation without affine terms (running statistics
    at inference). A map value has no scale of its own: the net can sharpen a softmax by scaling its maps up
    instead of lowering the temperature, and the strengths grow with it, where the positions stay in [-1, 1]."""

    def __init__(
        self,
        image_shape: tuple[int, int, int],
        channels: list[int],
        num_keypoints: int,
        shift: int = 0,
        pool: int = 1,
        strength: bool = False,
        strength_norm: bool = False,
    ):
        super().__init__()
        c, h, w = image_shape
        h, w = h // pool, w // pool  # the resolution the conv net sees (``pool``: average-pooling factor)
        layers: list[nn.Module] = []
        for i, out in enumerate(channels):
            k = 5 if i == 0 else 3
            layers += [nn.Conv2d(c, out, k, stride=2, padding=k // 2), nn.ReLU()]
            c, h, w = out, (h + 1) // 2, (w + 1) // 2
        layers.append(nn.Conv2d(c, num_keypoints, 3, padding=1))
        self.conv = nn.Sequential(*layers)
        self.softmax = SpatialSoftmax(h, w)
        self.shift = shift
        self.num_keypoints = num_keypoints
        self.strength = strength
        self.strength_norm = nn.BatchNorm1d(num_keypoints, affine=False) if strength and strength_norm else None
        self.out_dim = (3 if strength else 2) * num_keypoints
        self.pool = pool
        self.stride = pool * 2 ** len(channels)  # image pixels per keypoint-map cell
        self.map_shape = (h, w)

    def forward(self, images: Tensor) -> Tensor:
        xy, strength = self.softmax.attend(self.feature_maps(images))
        if not self.strength:
            return xy
        if self.strength_norm is not None:
            strength = self.strength_norm(strength)
        return torch.cat([xy, strength], dim=-1)

    def feature_maps(self, images: Tensor) -> Tensor:
        """The keypoint maps ``(N, num_keypoints, *map_shape)`` before the softmax: scaled, shifted (training),
        pooled and convolved images."""
        x = images.float() / 255.0 if images.dtype == torch.uint8 else images
        if self.training and self.shift > 0:
            x = random_shift(x, self.shift)
        if self.pool > 1:
            x = F.avg_pool2d(x, self.pool)
        return self.conv((x - 0.5) * 4.0)

    def pixel_coordinates(self, keypoints: Tensor) -> Tensor:
        """``(N, 2K)`` keypoints as this encoder outputs them (a strength after them is ignored) -> ``(N, K, 2)``
        image coordinates (column, row).

        A keypoint is ``(x, y)``: x runs along a map's columns (the image's width), y along its rows, each from -1
        at the first cell's centre to 1 at the last's (``SpatialSoftmax``'s grid). Map cell ``j`` is centred on
        pooled pixel ``2 ** layers * j``: every strided layer's kernel is centred on input index ``2 * j`` (odd
        kernel, padding ``kernel // 2``) and the last conv keeps the resolution; pooled pixel ``q`` averages image
        pixels ``pool * q`` to ``pool * q + pool - 1``. The result is in the convention of image viewers (pixel
        ``(i, j)`` covers ``[j, j + 1] x [i, i + 1]``), so a pooled pixel's centre is at ``+ pool / 2``."""
        h, w = self.map_shape
        xy = keypoints[:, : 2 * self.num_keypoints].reshape(keypoints.shape[0], -1, 2)
        cells = (xy + 1) / 2 * xy.new_tensor([w - 1, h - 1])
        return cells * self.stride + self.pool / 2


def random_shift(images: Tensor, shift: int) -> Tensor:
    """Each image moved by a random whole number of pixels in ``[-shift, shift]`` in x and y, its border repeated
    (DrQ's augmentation: replicate-pad, then crop at a random offset, as one ``grid_sample``)."""
    n, _, h, w = images.shape
    padded = F.pad(images, (shift, shift, shift, shift), mode="replicate")
    hp, wp = h + 2 * shift, w + 2 * shift
    # sampling grid of the unshifted crop, in the padded image's normalised coordinates (pixel centres)
    xs = (torch.arange(w, device=images.device, dtype=images.dtype) + shift + 0.5) * 2 / wp - 1
    ys = (torch.arange(h, device=images.device, dtype=images.dtype) + shift + 0.5) * 2 / hp - 1
    base = torch.stack(torch.meshgrid(ys, xs, indexing="ij")[::-1], dim=-1)  # (h, w, 2) as (x, y)
    offsets = torch.randint(-shift, shift + 1, (n, 1, 1, 2), device=images.device).to(images.dtype)
    offsets = offsets * torch.tensor([2.0 / wp, 2.0 / hp], device=images.device, dtype=images.dtype)
    return F.grid_sample(padded, base.unsqueeze(0) + offsets, mode="nearest", align_corners=False)
