"""Our errors as one line in a stock LeRobot console script (``lerobot-train``, ``lerobot-eval`` ...).

``install_cli_excepthook`` prints a ``PnPError`` (or an offline miss, see ``one_line_message``) as
``lerobot-train: error: <message>`` and exits with status 2, as ``lerobot-pnp`` does; ``registration`` installs
it in a stock script whose run is ours.
"""

from __future__ import annotations

from lerobot_pnp.errors import PnPError, one_line
from lerobot_pnp.stock_cli import dataset_roots_from_argv, stock_script

DEBUG_ENV = "LEROBOT_PNP_DEBUG"  # set (to anything): the hook leaves the traceback


def one_line_message(err: BaseException) -> str | None:
    """The one line a LeRobot CLI user should see for ``err``, or None when it is not ours to shorten.

    Ours: a ``PnPError`` anywhere in the exception chain (raised inside LeRobot's own code, e.g. by the env
    config or the policy, and perhaps wrapped); Hugging Face's ``OfflineModeIsEnabled`` (a dataset or model
    that is neither on disk nor reachable with ``HF_HUB_OFFLINE=1``); and its ``HFValidationError`` for a
    ``--policy.path`` that names a folder which does not exist.
    """
    seen: set[int] = set()
    while err is not None and id(err) not in seen:
        seen.add(id(err))
        if isinstance(err, PnPError):
            return one_line(err)
        if type(err).__name__ == "OfflineModeIsEnabled":
            return _offline_line(str(err))
        if type(err).__name__ == "HFValidationError" and (path := _missing_local_path(str(err))):
            return f"{path!r} is neither a folder on disk nor a Hub repo id (a checkpoint is a pretrained_model folder)"
        err = err.__cause__ or (None if err.__suppress_context__ else err.__context__)  # the chain Python prints
    return None


def _offline_line(message: str) -> str:
    import re

    found = re.search(r"/api/(datasets|models)/([^/\s]+/[^/\s]+)", message)
    kind, repo = (found.group(1)[:-1], found.group(2)) if found else ("file", "the requested repo")
    roots = dataset_roots_from_argv()
    if kind == "dataset" and roots:
        fix = f"--dataset.root {roots[-1]!r} holds no dataset: point it at a folder written by `lerobot-pnp generate`"
    elif kind == "dataset":
        fix = "pass --dataset.root=<folder> (a folder written by `lerobot-pnp generate`)"
    else:
        fix = "pass --policy.path=<local checkpoint folder>"
    return f"{kind} {repo!r} is not on disk and the Hub is offline (HF_HUB_OFFLINE=1): {fix}, or unset HF_HUB_OFFLINE"


def _missing_local_path(message: str) -> str | None:
    """The path-like repo id of a Hub validation error (a mistyped ``--policy.path``), if it is not on disk."""
    import re
    from pathlib import Path

    found = re.search(r"'([^']*/[^']*)'", message)
    if found is None or not found.group(1).startswith(("/", ".", "~")) or Path(found.group(1)).expanduser().exists():
        return None
    return found.group(1)


def install_cli_excepthook() -> None:
    """In a stock LeRobot console script (``lerobot-train``, ``lerobot-eval`` ...), print our errors as one line.

    LeRobot's CLIs have no error hook of their own, so an uncaught ``PnPError`` (or an offline miss, see
    ``one_line_message``) would end in a 50-250-line traceback with our message at the bottom. This hook prints
    ``lerobot-train: error: <message>`` instead and exits with status 2, as ``lerobot-pnp`` and argparse do for a
    user's mistake (the process's exit functions run first); every other exception goes to the previous hook
    unchanged (status 1). Scoped: installed only in a ``lerobot-*`` script whose run is
    ours (``registration.install_stock_hooks``: our env, policy or data), and ``LEROBOT_PNP_DEBUG=1`` restores
    the full traceback.
    """
    import os
    import sys

    prog = stock_script()
    if prog is None or os.environ.get(DEBUG_ENV):
        return
    previous = sys.excepthook

    def hook(exc_type, exc, tb):
        line = one_line_message(exc) if isinstance(exc, Exception) else None
        if line is None:
            previous(exc_type, exc, tb)
            return
        name = prog.removesuffix(".py").replace("_", "-")
        print(f"{name}: error: {line}\n({DEBUG_ENV}=1 shows the traceback)", file=sys.stderr)
        _exit(2)

    sys.excepthook = hook


def _exit(status: int) -> None:
    """End the process with ``status`` from inside ``sys.excepthook`` (where Python would give 1): flush the
    streams and run the exit functions (logging's shutdown among them) as a normal exit would, then leave."""
    import atexit
    import os
    import sys

    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    atexit._run_exitfuncs()
    os._exit(status)
