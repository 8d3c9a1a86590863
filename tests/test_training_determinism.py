"""A training of one seed gives bit-identical weights in fresh processes, whatever the caller's thread count, the
process's hash seed or the order of the trainings in it; another seed gives other weights. For the study's
trainings whose rates moved in a rerun: the phase-told MLP, ACT, a DAgger and a DART round (tiny sizes)."""

import json
import os
import subprocess
import sys

import pytest

from lerobot_pnp.report import adapters

N = 8  # demonstrations of each recording
SEEDS = (1000, 1001)

# One process: set the caller's torch thread count, train each of the study's methods for each seed in turn, print
# a digest of each checkpoint's weights. DAgger and DART run 2 rollouts a round, not the study's 300.
WORKER = """
import hashlib, json, sys
from dataclasses import replace
from pathlib import Path
import torch
from safetensors.torch import load_file
from lerobot_pnp.integration.registration import register_all
register_all()
from lerobot_pnp.report import methods
from lerobot_pnp.report.method_spec import TrainContext

root, out, threads = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[4])
torch.set_num_threads(threads)
digests = {}
for name in sys.argv[3].split(","):
    method = methods.METHODS[name]
    if method.schedule:
        methods.METHODS[name] = method = replace(method, schedule={**method.schedule, "rollouts_per_round": 2})
    data = root / ("dataset_phase" if method.data == "phase" else "dataset")
    digests[name] = {}
    for seed in map(int, sys.argv[5].split(",")):
        ctx = TrainContext(data, out / name / f"seed{seed}", seed, epochs=10, dense_root=root / "dataset_dense",
                           act_steps=30, task_budget=10, recipe_changes={"num_layers": 1})
        weights = load_file(str(Path(method.train(ctx)) / "model.safetensors"))
        digest = hashlib.sha256()
        for key in sorted(weights):
            digest.update(key.encode() + weights[key].contiguous().numpy().tobytes())
        digests[name][seed] = digest.hexdigest()
print("DIGESTS " + json.dumps(digests))
"""


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """The same demonstrations recorded as the study records them: keyframes, with the phase observed, dense."""
    root = tmp_path_factory.mktemp("determinism")
    adapters.generate_dataset(root / "dataset", N, seed=0, workers=1)
    adapters.generate_dataset(root / "dataset_phase", N, seed=0, workers=1, env_changes={"observe_phase": True})
    adapters.generate_dataset(root / "dataset_dense", N, seed=0, workers=1, control_mode="dense")
    return root


def _start(recordings, out, names, threads: int, hash_seed: str, seeds) -> subprocess.Popen:
    """A fresh process training each method of ``names`` for ``seeds`` in turn on ``threads`` torch threads."""
    args = [str(recordings), str(out), ",".join(names), str(threads), ",".join(map(str, seeds))]
    env = {**os.environ, "PYTHONHASHSEED": hash_seed}
    return subprocess.Popen([sys.executable, "-c", WORKER, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)  # fmt: skip


METHODS = ["phase_told_mlp", "act", "recovering_dagger", "recovering_dart"]


@pytest.fixture(scope="module")
def two_processes(recordings, tmp_path_factory) -> list[dict[str, dict[int, str]]]:
    """Each method's and seed's weights digest from two fresh processes run side by side: one on 1 thread with the
    methods and seeds in order, one on 2 threads with another hash seed and the methods and seeds in reverse."""
    tmp = tmp_path_factory.mktemp("trainings")
    procs = [
        _start(recordings, tmp / "first", METHODS, 1, "1", SEEDS),
        _start(recordings, tmp / "second", METHODS[::-1], 2, "2", SEEDS[::-1]),
    ]
    digests = []
    for proc in procs:
        out, err = proc.communicate(timeout=900)
        assert proc.returncode == 0, err[-3000:]
        line = next(x for x in out.splitlines() if x.startswith("DIGESTS "))
        found = json.loads(line.removeprefix("DIGESTS "))
        digests.append({name: {int(k): v for k, v in seeds.items()} for name, seeds in found.items()})
    return digests


@pytest.mark.parametrize("method", METHODS)
def test_a_seed_trains_the_same_weights_in_fresh_processes_and_another_seed_other_ones(two_processes, method):
    first, second = (digests[method] for digests in two_processes)
    assert first == second  # per seed: bit-identical weights, whatever the thread count, hash seed or order
    assert first[SEEDS[0]] != first[SEEDS[1]]


def test_a_training_block_is_seeded_on_fixed_threads_and_deterministic_algorithms_and_restores_them():
    import torch

    from lerobot_pnp.support.determinism import deterministic_training

    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        before = (torch.are_deterministic_algorithms_enabled(), torch.backends.mkldnn.deterministic)
        with deterministic_training(7):
            assert torch.get_num_threads() == 1
            assert torch.are_deterministic_algorithms_enabled() and torch.backends.mkldnn.deterministic
            draw = torch.rand(3)
        assert torch.get_num_threads() == 2
        assert (torch.are_deterministic_algorithms_enabled(), torch.backends.mkldnn.deterministic) == before
        with deterministic_training(7, threads=None):
            assert torch.get_num_threads() == 2  # None: the caller's count
            assert torch.equal(torch.rand(3), draw)  # seeded at the start of the block
    finally:
        torch.set_num_threads(threads)
