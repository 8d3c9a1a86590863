"""A camera sensor's faults on a rendered image: Gaussian blur (optics out of focus), then Gaussian noise.

Plain numpy on the HxWx3 uint8 frames the env renders, kept cheap because it runs on every frame of every camera:

* the blur is separable, its kernel cut at 3 standard deviations, edges repeated, in float32 over the image's rows
  as flat arrays;
* the noise is drawn as 16 random bits per pixel and channel (``Generator.bytes``, the cheapest draw numpy has),
  each mapped through a table of the Gaussian's inverse distribution at 65536 levels (``noise_table``): a
  Gaussian to 4.3 standard deviations, rounded to whole pixel values, added in integers and clipped.
"""

from __future__ import annotations

import functools
import math
from statistics import NormalDist

import numpy as np

LEVELS = 1 << 16  # noise levels: one per value of 16 random bits


def gaussian_kernel(sigma: float) -> np.ndarray:
    """The normalised 1-D Gaussian of std ``sigma`` pixels, cut at 3 std (at least 3 taps)."""
    radius = max(1, math.ceil(3 * sigma))
    x = np.arange(-radius, radius + 1, dtype=np.float32)
    k = np.exp(-0.5 * (x / np.float32(sigma)) ** 2)
    return (k / k.sum()).astype(np.float32)


def blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """``image`` (HxWxC) blurred by a Gaussian of std ``sigma`` pixels, as float32 (unchanged for sigma 0)."""
    if sigma <= 0:
        return image.astype(np.float32)
    k = gaussian_kernel(sigma)
    r = len(k) // 2
    h, w, c = image.shape
    padded = np.pad(image, ((r, r), (r, r), (0, 0)), mode="edge").astype(np.float32).reshape(h + 2 * r, -1)
    rows = _weighted_sum(k, [padded[i : i + h] for i in range(len(k))])  # down the columns
    out = _weighted_sum(k, [rows[:, i * c : i * c + w * c] for i in range(len(k))])  # along the rows
    return out.reshape(h, w, c)


def _weighted_sum(k: np.ndarray, views: list[np.ndarray]) -> np.ndarray:
    """``sum(k[i] * views[i])`` with two buffers (no array made per term)."""
    out = np.multiply(views[0], k[0])
    term = np.empty_like(out)
    for weight, view in zip(k[1:], views[1:], strict=True):
        np.multiply(view, weight, out=term)
        out += term
    return out


@functools.cache
def _standard_levels() -> np.ndarray:
    """The standard normal's quantile at the middle of each of ``LEVELS`` equal-probability bins."""
    inv = NormalDist().inv_cdf
    return np.array([inv((i + 0.5) / LEVELS) for i in range(LEVELS)], dtype=np.float64)


@functools.lru_cache(maxsize=16)
def noise_table(std: float) -> np.ndarray:
    """int16 pixel offsets of Gaussian noise with std ``std`` (a fraction of full scale), one per level."""
    return np.rint(_standard_levels() * (255.0 * std)).astype(np.int16)


def degrade(image: np.ndarray, blur_sigma: float, noise_std: float, rng: np.random.Generator) -> np.ndarray:
    """The image a faulty sensor returns: blurred, then noise of std ``noise_std`` (fraction of full scale) drawn
    from ``rng``; uint8. Draws from ``rng`` only when there is noise."""
    out = image if blur_sigma <= 0 else np.rint(blur(image, blur_sigma))
    if noise_std <= 0:
        return out.astype(np.uint8) if out is not image else image
    bits = np.frombuffer(rng.bytes(2 * image.size), dtype="<u2").reshape(image.shape)
    noisy = out.astype(np.int16) + np.take(noise_table(float(noise_std)), bits)
    return np.clip(noisy, 0, 255).astype(np.uint8)
