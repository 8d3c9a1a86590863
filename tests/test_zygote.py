"""The tests' forked runs (tests/zygote.py) behave as the processes they stand for: a process of its own, in its
folder and environment, with nothing of this project loaded before the program runs; exit status, uncaught
exceptions and signals as the interpreter gives them; a console script prints what its executable prints."""

from __future__ import annotations

import json
import signal
import sys

import pytest
import zygote
from clis import exe
from clis import run as run_executable

_WHERE = """
import json, os, sys
print(json.dumps({"ours": sorted(m for m in sys.modules if m.startswith(("lerobot_pnp", "lerobot_policy"))),
                  "torch": "torch" in sys.modules, "argv": sys.argv, "cwd": os.getcwd(), "pid": os.getpid(),
                  "path0": sys.path[0], "offline": os.environ.get("HF_HUB_OFFLINE"), "main": __name__}))
"""


def test_a_run_is_a_process_of_its_own_with_nothing_of_ours_loaded(tmp_path):
    proc = zygote.run([sys.executable, "-c", _WHERE, "a", "b"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout)
    assert seen["ours"] == [] and seen["torch"]  # torch preloaded, nothing of this project
    assert seen["argv"] == ["-c", "a", "b"] and seen["path0"] == "" and seen["main"] == "__main__"
    assert seen["cwd"] == str(tmp_path) and seen["offline"] == "1"
    assert seen["pid"] not in (zygote._zygote.proc.pid, __import__("os").getpid())


def test_exit_status_exceptions_and_signals_are_the_interpreters(tmp_path):
    assert zygote.run([sys.executable, "-c", "raise SystemExit(3)"], tmp_path).returncode == 3
    proc = zygote.run([sys.executable, "-c", "raise ValueError('boom')"], tmp_path)
    assert proc.returncode == 1 and "Traceback" in proc.stderr and "ValueError: boom" in proc.stderr
    child = zygote.start([sys.executable, "-c", "import time; time.sleep(60)"], tmp_path)
    assert child.poll() is None
    child.send_signal(signal.SIGKILL)
    assert child.wait(30) == -signal.SIGKILL
    code = "import signal, time; print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)"
    assert zygote.run([sys.executable, "-c", code], tmp_path, sigint=True).stdout.strip() == "True"


def test_a_run_ends_as_the_interpreter_ends_it(tmp_path):
    """Non-daemon threads finish, then the ``atexit`` functions run and the streams flush; a ``SystemExit``
    message goes to the standard error with status 1."""
    code = (
        "import atexit, sys, threading, time\n"
        "atexit.register(lambda: print('atexit', flush=False))\n"
        "threading.Thread(target=lambda: (time.sleep(0.3), print('thread'))).start()\n"
        "sys.stdout.write('unflushed ')\n"
    )
    proc = zygote.run([sys.executable, "-c", code], tmp_path)
    assert (proc.returncode, proc.stdout) == (0, "unflushed thread\natexit\n")
    proc = zygote.run([sys.executable, "-c", "raise SystemExit('stopped here')"], tmp_path)
    assert (proc.returncode, proc.stderr) == (1, "stopped here\n")
    proc = zygote.run([sys.executable, "-c", "raise KeyboardInterrupt"], tmp_path)
    assert proc.returncode == -signal.SIGINT and proc.stderr.rstrip().endswith("KeyboardInterrupt")


def test_communicate_waits_for_every_holder_of_the_streams(tmp_path):
    """As with ``subprocess.Popen``: a child's own child that outlives it (a pool's manager) still holds the pipes,
    so ``communicate`` returns after it is done (a test that resumes a killed run relies on it)."""
    code = "import os, time\nif os.fork() == 0:\n    time.sleep(1)\n    print('late', flush=True)\n    os._exit(0)\n"
    out, _ = zygote.start([sys.executable, "-c", code], tmp_path).communicate(timeout=60)
    assert out == "late\n"


def test_a_console_script_prints_what_its_executable_prints(tmp_path):
    real = run_executable([exe("lerobot-pnp"), "--help"], tmp_path, timeout=60)
    forked = zygote.run([exe("lerobot-pnp"), "--help"], tmp_path, timeout=60)
    assert (forked.returncode, forked.stdout, forked.stderr) == (real.returncode, real.stdout, real.stderr)
    assert forked.returncode == 0 and "usage: lerobot-pnp" in forked.stdout


def test_a_run_in_another_environment_is_refused():
    """What the preloaded libraries read when imported cannot change after the fork: such a run is refused."""
    with pytest.raises(ValueError, match="HF_HOME"):
        zygote.start([sys.executable, "-c", "pass"], env={**zygote.ENV, "HF_HOME": "/elsewhere"})
    with pytest.raises(ValueError, match="MUJOCO_GL"):
        zygote.start([sys.executable, "-c", "pass"], env={**zygote.ENV, "MUJOCO_GL": "osmesa"})
