"""A camera sensor's faults on a rendered image: Gaussian blur (optics out of focus), then Gaussian noise.

Plain numpy on the HxWx3 uint8 frames the env renders: a separable blur (the kernel cut at 3 standard deviations,
edges repeated) and additive noise, clipped and rounded back to uint8.
"""

from __future__ import annotations

import math

import numpy as np


def gaussian_kernel(sigma: float) -> np.ndarray:
    """The normalised 1-D Gaussian of std ``sigma`` pixels, cut at 3 std (at least 3 taps)."""
    radius = max(1, math.ceil(3 * sigma))
    x = np.arange(-radius, radius + 1, dtype=np.float32)
    k = np.exp(-0.5 * (x / sigma) ** 2)
    return k / k.sum()


def blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """``image`` (HxWxC) blurred by a Gaussian of std ``sigma`` pixels, as float32 (unchanged for sigma 0)."""
    out = image.astype(np.float32)
    if sigma <= 0:
        return out
    k = gaussian_kernel(sigma)
    r = len(k) // 2
    for axis in (0, 1):
        pad = [(0, 0)] * out.ndim
        pad[axis] = (r, r)
        padded = np.pad(out, pad, mode="edge")
        n = out.shape[axis]
        acc = np.zeros_like(out)
        for i, w in enumerate(k):
            acc += w * np.take(padded, np.arange(i, i + n), axis=axis)
        out = acc
    return out


def degrade(image: np.ndarray, blur_sigma: float, noise_std: float, rng: np.random.Generator) -> np.ndarray:
    """The image a faulty sensor returns: blurred, then noise of std ``noise_std`` (fraction of full scale) drawn
    from ``rng``; uint8. Draws from ``rng`` only when there is noise."""
    out = blur(image, blur_sigma)
    if noise_std > 0:
        out += rng.standard_normal(out.shape, dtype=np.float32) * np.float32(255 * noise_std)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
