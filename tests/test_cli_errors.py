"""The CLI never shows a traceback for a user mistake or an operational problem: one line, exit status 2."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from lerobot_pnp import cli

BIN = Path(sys.executable).parent
ENV = {**os.environ, "OMP_NUM_THREADS": "1", "HF_HUB_OFFLINE": "1"}


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["expert", "--config_path"], "--config_path needs a file"),
        (["expert", "--config_path", "--n_episodes", "3"], "--config_path needs a file"),
        (["expert", "--config_path=nowhere.json"], "no such file"),
        (["expert", "--seed", "99999999999999999999999"], "seed must be an integer in [0, 2**63"),
        (["expert", "--n_episodes", "abc"], "n_episodes"),
        (["expert", "--env.nudge_max", "-1"], "env.nudge_max must be in [0, 1)"),
        (["expert", "--env.preset", "hard"], "env.preset must be one of ['full', 'paper']"),
        (["expert", "--env.control_mode", "teleport"], "env.control_mode must be one of"),
        (["expert", "--env.object_low", "[0.9,0.1]", "--env.object_high", "[1.2,0.5]"], "out of the arm's reach"),
        (["expert", "--env.keyframe_budget", "3"], "env.keyframe_budget must be an integer in [10"),
    ],
)
def test_user_mistakes_are_one_line_and_exit_2(argv, message, capsys):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupt_is_one_line_and_exit_2(sig, tmp_path):
    exe = BIN / "lerobot-pnp"
    if not exe.exists():
        pytest.skip(f"lerobot-pnp is not installed next to {sys.executable}")
    proc = subprocess.Popen(
        [str(exe), "expert", "--n_episodes", "100000"],
        cwd=tmp_path,
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    seen = b""
    deadline = time.monotonic() + 120
    while b"expert episodes" not in seen and time.monotonic() < deadline:  # the progress bar: inside the loop
        seen += os.read(proc.stderr.fileno(), 4096)
    time.sleep(0.5)
    proc.send_signal(sig)
    _, rest = proc.communicate(timeout=60)
    err = (seen + rest).decode(errors="replace")
    assert proc.returncode == 2, err
    assert "interrupted" in err and "Traceback" not in err, err
