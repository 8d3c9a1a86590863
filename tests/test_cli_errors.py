"""The CLI never shows a traceback for a user mistake or an operational problem: one line, exit status 2."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zygote

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
    # in a process of its own forked from a warm interpreter (tests/zygote.py), with SIGINT as in a terminal (a
    # background job, ``cmd &`` or a CI runner, starts its children with it ignored)
    proc = zygote.start([str(exe), "expert", "--n_episodes", "100000"], tmp_path, sigint=True)
    deadline = time.monotonic() + 120
    while "expert episodes" not in proc.stderr_so_far() and time.monotonic() < deadline:  # the progress bar
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2, err
    assert "interrupted" in err and "Traceback" not in err, err


def test_a_second_sigterm_terminates_instead_of_interrupting_the_unwinding():
    """The first SIGTERM becomes KeyboardInterrupt; a second one (a process-group kill repeated while the first
    unwinds and joins worker processes) must not raise again inside the interpreter's exit hooks (a traceback)."""
    previous = signal.getsignal(signal.SIGTERM)
    try:
        signal.signal(signal.SIGTERM, cli._sigterm_as_interrupt)
        with pytest.raises(KeyboardInterrupt):
            cli._sigterm_as_interrupt(signal.SIGTERM, None)
        assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_viz_of_a_dataset_with_nan_is_one_line_naming_episode_and_frame(tmp_path, capsys):
    """The viewer fails with a clear error rather than exiting 0 and printing NaN."""
    from keyframe_synth import REPO_ID, make_keyframe_dataset

    root = tmp_path / "nan"
    make_keyframe_dataset(root, n_episodes=3, nan_at=(1, 3))
    rrd = tmp_path / "ep.rrd"
    capsys.readouterr()  # the writer's own progress while making the test data
    rc = cli.main(["viz", "--repo_id", REPO_ID, "--root", str(root), "--episode_index", "1", "--save", str(rrd)])
    err = capsys.readouterr().err
    assert rc == 2 and "non-finite" in err and "episode 1, frame 3" in err, err
    assert len(err.strip().splitlines()) == 1 and not rrd.exists()


def test_lerobot_eval_rejects_bad_env_flags_before_loading_the_policy(tmp_path):
    """Through lerobot-eval's entry point (in a process forked from a warm interpreter, tests/zygote.py): the env
    config fails first, naming the flag."""
    exe = BIN / "lerobot-eval"
    if not exe.exists():
        pytest.skip(f"lerobot-eval is not installed next to {sys.executable}")
    policy = tmp_path / "no_such_checkpoint"  # never reached: the env config is parsed first
    for flag, message in (("--env.nudge_max=-1", "env.nudge_max must be in [0, 1)"),
                          ("--env.preset=hard", "env.preset must be one of")):  # fmt: skip
        cmd = [str(exe), f"--policy.path={policy}", "--env.type=baxter_pnp", flag, f"--output_dir={tmp_path / 'o'}"]
        proc = zygote.run(cmd, tmp_path, timeout=120)
        assert proc.returncode != 0 and message in proc.stderr, proc.stderr[-2000:]
        assert not (tmp_path / "o" / "eval_info.json").exists()


# ------------------------------------------------------------------------ errors through stock lerobot-* CLIs
_FAKE_CLI = """
import sys
import lerobot_policy_pnp_lstm  # what LeRobot's plugin discovery imports
from lerobot_pnp.errors import ConfigError
try:
    raise ConfigError("env.speed must be in (0, 1], got 7")
except ConfigError as err:
    if sys.argv[1:] == ["--env.type=baxter_pnp", "other"]:
        raise ValueError("not ours") from None
    raise RuntimeError("LeRobot wrapped it") from err
"""


@pytest.mark.parametrize(
    ("script", "extra_env", "arg", "one_line"),
    [
        ("lerobot-fake", {}, "ours", True),
        ("lerobot-fake", {"LEROBOT_PNP_DEBUG": "1"}, "ours", False),  # the debug switch keeps the traceback
        ("lerobot-fake", {}, "other", False),  # an error that is not ours keeps its traceback
        ("my_script.py", {}, "ours", False),  # only stock lerobot-* scripts are affected
        ("lerobot-fake", {}, "unrelated", False),  # a run on no env, policy or data of ours: no hook at all
    ],
)
def test_our_errors_are_one_line_in_a_lerobot_script(tmp_path, script, extra_env, arg, one_line):
    path = tmp_path / script
    path.write_text(_FAKE_CLI)
    env = {**ENV, **extra_env, "PYTHONPATH": os.pathsep.join(sys.path)}
    args = [] if arg == "unrelated" else ["--env.type=baxter_pnp", *([arg] if arg == "other" else [])]
    proc = subprocess.run([sys.executable, str(path), *args], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert proc.returncode == (2 if one_line else 1), proc.stderr[-2000:]
    if one_line:
        assert "Traceback" not in proc.stderr, proc.stderr
        assert "lerobot-fake: error: env.speed must be in (0, 1], got 7" in proc.stderr.splitlines()[-2]
        assert "LEROBOT_PNP_DEBUG=1" in proc.stderr.splitlines()[-1]
    else:
        assert "Traceback" in proc.stderr, proc.stderr


@pytest.mark.slow
def test_lerobot_train_on_a_missing_dataset_offline_is_one_line(tmp_path):
    exe = BIN / "lerobot-train"
    if not exe.exists():
        pytest.skip(f"lerobot-train is not installed next to {sys.executable}")
    missing = tmp_path / "no_dataset"
    cmd = [str(exe), "--dataset.repo_id=local/nothing", f"--dataset.root={missing}", "--policy.type=pnp_lstm"]
    cmd += ["--policy.push_to_hub=false", "--steps=1", f"--output_dir={tmp_path / 'out'}"]
    proc = zygote.run(cmd, tmp_path, timeout=120)  # lerobot-train's entry point in a process forked from a warm one
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "OfflineModeIsEnabled" not in proc.stderr, proc.stderr[-3000:]
    assert f"--dataset.root '{missing}' holds no dataset" in proc.stderr
