"""The README's quick start runs as written from a clean folder, at a small size.

The commands are read from the README (between ``<!-- quickstart -->`` and ``<!-- end quickstart -->``) and run
one after the other with the installed executables; only their size flags are made small (episodes, epochs,
rollouts). Each must exit 0 and write what the README's table says it writes.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
ENV = {**os.environ, "OMP_NUM_THREADS": "1", "HF_HUB_OFFLINE": "1", "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
# flag -> the small value it runs with here; each must appear in the quick start (else the README changed shape)
SMALL = {
    "--num_episodes": "4",
    "--epochs": "1",
    "--eval.n_episodes": "2",
    "--eval.batch_size": "2",
    "--n_episodes": "1",
}
# what the README's table says each command writes, relative to the folder it runs in
WRITES = {
    "generate": ["outputs/datasets/baxter_pnp_keyframe/meta/info.json",
                 "outputs/datasets/baxter_pnp_keyframe/meta/baxter_pnp_env.json"],
    "train": ["outputs/fast_lstm/checkpoints/last/pretrained_model/config.json", "outputs/fast_lstm/loss_curve.png",
              "outputs/fast_lstm/test_keyframe_error.json"],
    "lerobot-eval": ["outputs/eval_lstm/eval_info.json"],
    "viz": ["outputs/rollouts.rrd"],
}  # fmt: skip


def quickstart_commands(readme: str) -> list[list[str]]:
    """The quick start's commands, split as a shell would."""
    block = re.search(r"<!-- quickstart -->\s*```bash\n(.*?)```\s*<!-- end quickstart -->", readme, re.S)
    assert block, "README.md has no quick start between <!-- quickstart --> and <!-- end quickstart -->"
    text = block.group(1).replace("\\\n", " ")
    return [shlex.split(line, comments=True) for line in text.splitlines() if line.strip()]


def small(argv: list[str]) -> tuple[list[str], set[str]]:
    """``argv`` with every size flag of SMALL set to its small value, and the flags replaced."""
    out, seen = list(argv), set()
    for i, arg in enumerate(out):
        flag = arg.split("=", 1)[0]
        if flag in SMALL:
            seen.add(flag)
            if "=" in arg:
                out[i] = f"{flag}={SMALL[flag]}"
            else:
                out[i + 1] = SMALL[flag]
    return out, seen


def _name(argv: list[str]) -> str:
    return argv[1] if argv[0] == "lerobot-pnp" else argv[0]


def test_quickstart_is_generate_train_evaluate_view():
    commands = quickstart_commands((ROOT / "README.md").read_text())
    assert [_name(c) for c in commands] == list(WRITES)
    seen = set().union(*(small(c)[1] for c in commands))
    assert seen == set(SMALL), f"size flags missing from the quick start: {set(SMALL) - seen}"


@pytest.mark.slow
def test_quickstart_runs_as_written(tmp_path):
    for argv in quickstart_commands((ROOT / "README.md").read_text()):
        exe = BIN / argv[0]
        if not exe.exists():
            pytest.skip(f"{argv[0]} is not installed next to {sys.executable}")
        cmd, _ = small(argv)
        proc = subprocess.run([str(exe), *cmd[1:]], cwd=tmp_path, env=ENV, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, f"{shlex.join(cmd)} failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
        for rel in WRITES[_name(argv)]:
            assert (tmp_path / rel).is_file(), f"{shlex.join(cmd)} did not write {rel}"
