"""Console scripts and ``python -c`` code run in processes of their own, forked from a warm interpreter.

A fresh ``lerobot-pnp``, ``lerobot-eval`` or ``lerobot-train`` spends seconds of CPU importing torch and LeRobot
before its first line of work, and most tests that run one care about what it does after that. The zygote is an
interpreter of its own (started by the test process with this environment, never a fork of pytest and its
threads) that imports those third-party libraries once and nothing of this project; each run is a child forked
from it that runs the program as ``__main__`` with its own arguments, folder, standard streams, signals and
environment. ``lerobot_pnp`` and the plugin shim load in the child, as in a fresh process: LeRobot's plugin
discovery runs in the child's ``main``, with the child's command line. An uncaught exception goes to the child's
``sys.excepthook`` and ``SystemExit`` sets its exit status, as in the interpreter.

What the preloaded imports print is written to each child's own streams first, as a fresh process would print
it. What a child does not go through is the interpreter's start itself (the executable's shebang, the
interpreter's flags): a few tests per console script still start the executable (test_cli.py,
test_readme_quickstart.py, test_packaging.py, test_cli_end_to_end.py, test_plugin_scope.py ...). A run whose
environment differs from the zygote's in what the preloaded libraries read when imported is refused (start a
real process for it).
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import warnings
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
# imported once by the zygote: what every console script of ours or LeRobot's imports first (not MuJoCo, whose
# rendering backend is read from the environment when it is imported)
PRELOAD = ("torch", "lerobot.scripts.lerobot_eval", "lerobot.scripts.lerobot_train", "lerobot.datasets.lerobot_dataset")
# environment variables the preloaded libraries read when imported: a run must have the zygote's values
READ_AT_IMPORT = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "PYTHONPATH", "MUJOCO_GL", "PYTHONUNBUFFERED")
ENV = {
    **{k: v for k, v in os.environ.items() if not k.startswith("HF_")},
    "OMP_NUM_THREADS": "1",
    "HF_HUB_OFFLINE": "1",
    "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"),
    "PYTHONUNBUFFERED": "1",
    "PYTHONPATH": os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]),
}


# ---------------------------------------------------------------------------------------------- the test's side
class Forked:
    """A running child: ``pid``, ``poll``, ``wait``, ``send_signal``, ``kill``, ``communicate``, as
    ``subprocess.Popen`` with its standard output and error on pipes: ``communicate`` returns once every process
    that holds them (the child's own children too) has closed them."""

    def __init__(self, zygote: _Zygote, args: list[str], pid: int, pipes: tuple[int, int]):
        self.args, self.pid, self.returncode = args, pid, None
        self._zygote, self._read = zygote, [bytearray(), bytearray()]
        self._readers = [
            threading.Thread(target=_drain, args=(fd, buf), daemon=True) for fd, buf in zip(pipes, self._read)
        ]
        for reader in self._readers:
            reader.start()

    def poll(self) -> int | None:
        return self.wait(timeout=0, check=False)

    def wait(self, timeout: float | None = None, check: bool = True) -> int | None:
        if self.returncode is None:
            self.returncode = self._zygote.ask({"op": "wait", "pid": self.pid, "timeout": timeout})["returncode"]
        if self.returncode is None and check:
            raise subprocess.TimeoutExpired(self.args, timeout)
        return self.returncode

    def send_signal(self, sig: int) -> None:
        if self.returncode is None:
            os.kill(self.pid, sig)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)

    def stderr_so_far(self) -> str:
        return bytes(self._read[1]).decode(errors="replace")

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        deadline = None if timeout is None else time.monotonic() + timeout
        self.wait(timeout)
        for reader in self._readers:
            reader.join(None if deadline is None else max(0.0, deadline - time.monotonic()))
            if reader.is_alive():
                raise subprocess.TimeoutExpired(self.args, timeout)
        return tuple(bytes(buf).decode(errors="replace") for buf in self._read)


def _drain(fd: int, buf: bytearray) -> None:
    with os.fdopen(fd, "rb", buffering=0) as pipe:
        while chunk := pipe.read(1 << 16):
            buf.extend(chunk)


class _Zygote:
    def __init__(self):
        self.sock, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self.proc = subprocess.Popen([sys.executable, __file__, str(theirs.fileno())], pass_fds=[theirs.fileno()],
                                     env=ENV, cwd="/", stdin=subprocess.DEVNULL)  # fmt: skip
        theirs.close()
        atexit.register(self.close)

    def ask(self, request: dict, fds: list[int] = ()) -> dict:
        socket.send_fds(self.sock, [json.dumps(request).encode()], list(fds))
        reply = self.sock.recv(1 << 16)
        assert reply, f"the zygote ended (exit status {self.proc.wait()})"
        return json.loads(reply)

    def close(self) -> None:
        self.sock.close()
        self.proc.wait(timeout=30)


_zygote: _Zygote | None = None


def start(cmd: list[str], cwd: Path | str = "/", env: dict | None = None, *, new_session: bool = False,
          sigint: bool = False, max_file_size: int | None = None) -> Forked:  # fmt: skip
    """Start ``cmd`` in a child of the zygote: ``[<console script>, *args]`` (a path or a name of this venv's
    bin), ``[sys.executable, "-c", code, *args]`` or ``[sys.executable, "-m", module, *args]``. ``new_session``:
    its own session and process group; ``sigint``: Python's KeyboardInterrupt on SIGINT (a terminal's child; a
    background job's children ignore it); ``max_file_size``: RLIMIT_FSIZE in bytes."""
    global _zygote
    env = ENV if env is None else env
    differ = [
        k for k in (*READ_AT_IMPORT, *(k for k in {*env, *ENV} if k.startswith("HF_"))) if env.get(k) != ENV.get(k)
    ]
    if differ:
        raise ValueError(f"{differ} differ from the zygote's environment: start a real process for this run")
    if _zygote is None:
        _zygote = _Zygote()
    (out_r, out_w), (err_r, err_w) = os.pipe(), os.pipe()
    streams = [os.open(os.devnull, os.O_RDONLY), out_w, err_w]
    request = {"op": "start", "cmd": [str(c) for c in cmd], "cwd": str(cwd), "env": env, "new_session": new_session,
               "sigint": sigint, "max_file_size": max_file_size}  # fmt: skip
    try:
        pid = _zygote.ask(request, streams)["pid"]
    except BaseException:
        os.close(out_r), os.close(err_r)
        raise
    finally:
        for fd in streams:
            os.close(fd)
    return Forked(_zygote, [str(c) for c in cmd], pid, (out_r, err_r))


def run(cmd: list[str], cwd: Path | str = "/", timeout: float = 300, env: dict | None = None,
        **options) -> subprocess.CompletedProcess:  # fmt: skip
    """``start`` and wait: as ``subprocess.run(cmd, capture_output=True, text=True)``."""
    child = start(cmd, cwd, env, **options)
    try:
        out, err = child.communicate(timeout)
    except subprocess.TimeoutExpired:
        child.kill()
        child.wait(60)
        raise
    return subprocess.CompletedProcess(child.args, child.returncode, out, err)


# ---------------------------------------------------------------------------------------------- the zygote's side
def _serve(sock: socket.socket) -> dict:
    """Answer requests until one starts a child; return that request in the child (the zygote never returns)."""
    printed = _preload()
    assert not [m for m in sys.modules if m.startswith(("lerobot_pnp", "lerobot_policy_pnp"))]
    while True:
        msg, fds, _, _ = socket.recv_fds(sock, 1 << 16, 3)
        if not msg:  # the test process closed its end
            os._exit(0)
        request = json.loads(msg)
        if request["op"] == "start":
            sys.stdout.flush(), sys.stderr.flush()
            gc.freeze()  # the preloaded objects stay out of the child's collections: no copy of their pages, no sweep
            with warnings.catch_warnings():  # a native thread of jemalloc (pyarrow's) takes no lock fork needs
                warnings.simplefilter("ignore", DeprecationWarning)
                pid = os.fork()
            if pid == 0:
                sock.close()
                for target, fd in enumerate(fds):
                    os.dup2(fd, target)
                    os.close(fd)
                for target, text in printed.items():  # what the imports printed, as a fresh process prints it
                    os.write(target, text)
                return request
            for fd in fds:
                os.close(fd)
            sock.sendall(json.dumps({"pid": pid}).encode())
        else:
            sock.sendall(json.dumps({"returncode": _wait(request["pid"], request["timeout"])}).encode())


def _preload() -> dict[int, bytes]:
    """Import PRELOAD; return what the imports wrote to the standard output and error (fd -> bytes)."""
    import importlib

    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        files, saved = {1: out, 2: err}, {fd: os.dup(fd) for fd in (1, 2)}
        for fd, file in files.items():
            os.dup2(file.fileno(), fd)
        try:
            for name in PRELOAD:
                importlib.import_module(name)
        finally:
            sys.stdout.flush(), sys.stderr.flush()
            for fd in (1, 2):
                os.dup2(saved[fd], fd)
                os.close(saved[fd])
        return {fd: (file.seek(0), file.read())[1] for fd, file in files.items()}


def _wait(pid: int, timeout: float | None) -> int | None:
    deadline = None if timeout is None else time.monotonic() + timeout
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status)
        if deadline is not None and time.monotonic() >= deadline:
            return None
        time.sleep(0.01)


def _child(request: dict) -> None:
    """Become the program of ``request``: its folder, environment, session, signals and limits, then run it."""
    import resource
    import runpy
    import types

    os.chdir(request["cwd"])
    os.environ.clear()
    os.environ.update(request["env"])
    if request["new_session"]:
        os.setsid()
    if request["sigint"]:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if request["max_file_size"] is not None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (request["max_file_size"],) * 2)
    cmd = request["cmd"]
    if cmd[0] == sys.executable and cmd[1] == "-c":
        sys.argv, sys.path[0] = ["-c", *cmd[3:]], ""
        main = types.ModuleType("__main__")
        sys.modules["__main__"] = main
        exec(compile(cmd[2], "<string>", "exec"), main.__dict__)
    elif cmd[0] == sys.executable and cmd[1] == "-m":
        sys.argv, sys.path[0] = [cmd[2], *cmd[3:]], request["cwd"]
        runpy.run_module(cmd[2], run_name="__main__", alter_sys=True)
    else:
        script = Path(cmd[0]) if "/" in cmd[0] else BIN / cmd[0]
        sys.argv, sys.path[0] = [str(script), *cmd[1:]], str(script.parent)
        runpy.run_path(str(script), run_name="__main__")
    sys.exit(0)


def _exit_as_the_interpreter(request: dict) -> None:
    """Run the child's program, then end as the interpreter ends a program, less the teardown of the preloaded
    modules (about half a second of the child's time, which changes nothing a program can observe): an uncaught
    exception printed by ``sys.excepthook`` (status 1), ``SystemExit``'s status or message, an uncaught
    ``KeyboardInterrupt`` as death by SIGINT; then the wait for non-daemon threads, the ``atexit`` functions and
    the flush of the standard streams, in the interpreter's order."""
    import atexit
    import threading

    try:
        _child(request)
        status = 0
    except SystemExit as stop:
        if stop.code is None or isinstance(stop.code, int):
            status = stop.code or 0
        else:  # a message: printed, status 1
            print(stop.code, file=sys.stderr)
            status = 1
    except KeyboardInterrupt:
        sys.excepthook(*sys.exc_info())
        status = -signal.SIGINT
    except BaseException:
        sys.excepthook(*sys.exc_info())
        status = 1
    threading._shutdown()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed or broken stream: nothing left to flush
            stream.flush()
    if status == -signal.SIGINT:
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGINT)
    os._exit(status)


if __name__ == "__main__":
    _exit_as_the_interpreter(_serve(socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET, fileno=int(sys.argv[1]))))
