"""Seeded, deterministic training: the one place the trainers (``train_fast``, ACT's loop in ``report``, and through
``train_fast`` every DAgger and DART round) fix what a training's numbers depend on besides its data and seed.

On one machine a training of a given seed then gives bit-identical weights in any process, in any order:

* the global generators (Python's, numpy's, torch's) are seeded at the start of the training, so nothing drawn
  before it (another training in the same process, an evaluation, a rollout) shifts its draws: model
  initialisation, batch order (the trainers' own ``torch.Generator``, seeded from the same seed) and the
  augmentations that draw from torch's global generator;
* torch's intra-op thread count is fixed: a CPU kernel splits its reductions by thread, so another count sums
  in another order and gives other weights (ACT's transformer shows it within tens of steps);
* torch runs its deterministic algorithms, oneDNN's included; an operation that has none warns (on CPU none of
  these trainings uses one).

What it cannot fix: the kernels MKL, oneDNN and torch pick for the processor (its vendor and instruction
set) sum in their own order, so another CPU model can give weights that differ in their last bits, and a
training amplifies that difference step by step (docs/results/reproduce.md).
"""

from __future__ import annotations

import random
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import torch

# The trainers' thread count: the study and DAgger run every job single-threaded, and the tiny models train
# fastest on one thread.
TRAINING_THREADS = 1


def seed_everything(seed: int) -> None:
    """Seed Python's, numpy's and torch's global generators (LeRobot's ``set_seed``, with numpy's seed taken
    modulo 2**32: numpy accepts 32 bits, the configs accept seeds up to 2**63)."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


@contextmanager
def deterministic_training(seed: int, threads: int | None = TRAINING_THREADS) -> Iterator[None]:
    """A training block: the global generators seeded with ``seed``, torch on ``threads`` intra-op threads
    (None: the count it has) and on its deterministic algorithms. The thread count and the algorithm settings
    are restored after the block; the generators are left as the training leaves them."""
    before = (
        torch.get_num_threads(),
        torch.are_deterministic_algorithms_enabled(),
        torch.is_deterministic_algorithms_warn_only_enabled(),
        torch.backends.mkldnn.deterministic,
    )
    if threads is not None:
        torch.set_num_threads(threads)
    # warn_only: an operation without a deterministic version (on a GPU, cuBLAS without its workspace setting)
    # warns once instead of failing the training
    torch.use_deterministic_algorithms(True, warn_only=True)
    torch.backends.mkldnn.deterministic = True
    seed_everything(seed)
    try:
        yield
    finally:
        torch.set_num_threads(before[0])
        torch.use_deterministic_algorithms(before[1], warn_only=before[2])
        torch.backends.mkldnn.deterministic = before[3]
