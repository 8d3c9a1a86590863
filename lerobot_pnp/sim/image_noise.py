"""A camera sensor's faults on a rendered image: Gaussian blur (optics out of focus), then Gaussian noise.

Plain numpy on the HxWx3 uint8 frames the env renders, in integers, because it runs on every frame of every camera:

* the blur is separable, its kernel cut at 3 standard deviations and its weights in 1/256ths (a sum of 256, so a
  pass over uint8 values fits uint16 exactly), each pass rounded back to whole pixel values, edges repeated;
* the noise is one random byte per pixel and channel (``Generator.bytes``, numpy's cheapest draw), mapped through a
  table of the Gaussian's quantiles at 256 equally likely levels (``noise_table``): a Gaussian cut at 2.7 standard
  deviations, scaled so that its standard deviation is the one asked for; the noisy value of every (value, level)
  pair is one table (``noisy_values``), so a frame's noise is one lookup.
"""

from __future__ import annotations

import functools
import math
from statistics import NormalDist

import numpy as np

LEVELS = 256  # noise levels: one per value of a random byte
_ONE = 256  # the blur's weights are in 1/256ths


def gaussian_kernel(sigma: float) -> np.ndarray:
    """The normalised 1-D Gaussian of std ``sigma`` pixels, cut at 3 std (at least 3 taps), in float64."""
    radius = max(1, math.ceil(3 * sigma))
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / sigma) ** 2)
    return k / k.sum()


@functools.lru_cache(maxsize=16)
def integer_kernel(sigma: float) -> np.ndarray:
    """``gaussian_kernel`` in whole 1/256ths summing to exactly 256 (the rounding's remainder on the centre tap), the
    end taps that round to 0 left out."""
    w = np.rint(gaussian_kernel(sigma) * _ONE).astype(np.int64)
    w[len(w) // 2] += _ONE - int(w.sum())
    cut = int(np.argmax(w > 0))  # taps that round to 0 at both ends add nothing
    return w[cut : len(w) - cut].astype(np.uint16)


def _pass(w: np.ndarray, views) -> np.ndarray:
    """``sum(w[i] * views(i))`` rounded to whole values (uint16: every sum is at most 255 * 256 + 128)."""
    out = views(0) * w[0]
    for i in range(1, len(w)):
        out += views(i) * w[i]
    out += _ONE // 2
    out >>= 8
    return out


def _edge_padded(image: np.ndarray, r: int) -> np.ndarray:
    """``image`` as uint16 with ``r`` pixels of its edge repeated on every side (``np.pad``'s "edge", without its
    per-call cost, which on a small frame is most of the blur's)."""
    h, w, c = image.shape
    out = np.empty((h + 2 * r, w + 2 * r, c), dtype=np.uint16)
    out[r : r + h, r : r + w] = image
    out[r : r + h, :r] = image[:, :1]
    out[r : r + h, r + w :] = image[:, -1:]
    out[:r] = out[r : r + 1]
    out[r + h :] = out[r + h - 1 : r + h]
    return out


def blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """``image`` (HxWxC uint8) blurred by a Gaussian of std ``sigma`` pixels, as uint8 (a copy; sigma 0: unchanged)."""
    if sigma <= 0:
        return image.copy()
    w = integer_kernel(float(sigma))
    r = len(w) // 2
    h, width, c = image.shape
    padded = _edge_padded(image, r).reshape(h + 2 * r, -1)
    rows = _pass(w, lambda i: padded[i : i + h])  # down the columns
    out = _pass(w, lambda i: rows[:, i * c : i * c + width * c])  # along the rows
    return out.reshape(h, width, c).astype(np.uint8)


@functools.cache
def _standard_levels() -> np.ndarray:
    """The standard normal's quantile at the middle of each of ``LEVELS`` equally likely bins, scaled to std 1."""
    inv = NormalDist().inv_cdf
    levels = np.array([inv((i + 0.5) / LEVELS) for i in range(LEVELS)])
    return levels / levels.std()


@functools.lru_cache(maxsize=16)
def noise_table(std: float) -> np.ndarray:
    """int16 pixel offsets of Gaussian noise with std ``std`` (a fraction of full scale), one per level."""
    return np.rint(_standard_levels() * (255.0 * std)).astype(np.int16)


@functools.lru_cache(maxsize=16)
def noisy_values(std: float) -> np.ndarray:
    """The noisy pixel value for every (value, level) pair, at index ``value * 256 + level``: the value plus the
    level's offset (``noise_table``), clipped to 0..255 (uint8)."""
    values = np.arange(256, dtype=np.int16)[:, None] + noise_table(std)[None, :]
    return np.clip(values, 0, 255).astype(np.uint8).ravel()


def degrade(image: np.ndarray, blur_sigma: float, noise_std: float, rng: np.random.Generator) -> np.ndarray:
    """The image a faulty sensor returns: blurred, then noise of std ``noise_std`` (fraction of full scale) drawn
    from ``rng``; uint8. Draws from ``rng`` only when there is noise."""
    out = blur(image, blur_sigma) if blur_sigma > 0 else image
    if noise_std <= 0:
        return out
    index = out.astype(np.uint16) << 8
    index |= np.frombuffer(rng.bytes(image.size), dtype=np.uint8).reshape(image.shape)
    return np.take(noisy_values(float(noise_std)), index)
