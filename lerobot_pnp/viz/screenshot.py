"""A picture of what a user sees: the real Rerun viewer, run headless on a saved recording.

``rerun rec.rrd --headless --screenshot-to shot.png --window-size 1600x1000`` lays out the recording's
blueprint and renders it offscreen (wgpu; a software rasterizer is enough), so the picture is the viewer
itself, not a re-render. The viewer binary ships with ``rerun-sdk`` (``rerun`` beside the Python executable).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from lerobot_pnp.errors import PnPError
from lerobot_pnp.outputs import OutputFolder
from lerobot_pnp.viz.config import COMMAND

TIMEOUT_S = 180
# What the viewer prints when this machine has no graphics adapter wgpu can use (the one condition under
# which a screenshot cannot be taken here; any other failure is an error).
NO_ADAPTER = re.compile(r"no (suitable )?wgpu adapter|didn't find compatible adapters", re.IGNORECASE)


class ViewerUnavailableError(PnPError):
    """The Rerun viewer cannot render on this machine (no viewer binary, or no graphics adapter)."""


class ScreenshotError(PnPError):
    """The Rerun viewer ran but did not write the screenshot."""


def viewer_binary() -> str:
    """The ``rerun`` viewer executable of this Python environment (else the one on PATH)."""
    exe = shutil.which("rerun", path=str(Path(sys.executable).parent)) or shutil.which("rerun")
    if exe is None:
        raise ViewerUnavailableError("the Rerun viewer binary `rerun` is not installed (pip install rerun-sdk)")
    return exe


def take_screenshot(recording: str | Path, out: str | Path, window: tuple[int, int] = (1600, 1000)) -> Path:
    """Render ``recording`` (an .rrd with its blueprint) in the headless viewer and save a PNG to ``out``.

    The viewer writes into a temporary folder; the picture then goes into ``out``'s folder through
    ``lerobot_pnp.outputs`` (atomically, and only over a file ``lerobot-pnp viz`` wrote there)."""
    out = Path(out).expanduser().resolve()
    with tempfile.TemporaryDirectory(prefix="lerobot_pnp_shot_") as tmp_dir:
        tmp = Path(tmp_dir) / "shot.png"
        cmd = [viewer_binary(), str(recording), "--headless", "--screenshot-to", str(tmp)]
        cmd += ["--window-size", f"{window[0]}x{window[1]}", "--port", "auto"]  # never clash with a running viewer
        # RUST_LOG=warn: no info notifications ("Listening for gRPC connections ...") drawn over the picture.
        env = {**os.environ, "RERUN_ANALYTICS": "0", "RUST_LOG": "warn"}
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S, env=env)
        except subprocess.TimeoutExpired:
            raise ScreenshotError(f"the headless Rerun viewer did not finish within {TIMEOUT_S} s") from None
        log = proc.stdout + proc.stderr
        if NO_ADAPTER.search(log):
            found = NO_ADAPTER.search(log)[0]
            raise ViewerUnavailableError(f"the Rerun viewer found no graphics adapter here: {found}")
        if proc.returncode != 0 or not tmp.is_file():
            last = [line for line in log.strip().splitlines() if line.strip()][-1:] or ["(no output)"]
            raise ScreenshotError(f"the headless Rerun viewer failed (exit {proc.returncode}): {last[0][-300:]}")
        with OutputFolder(out.parent, COMMAND, flag="--screenshot") as folder:
            folder.write_bytes(out.name, tmp.read_bytes())
    return out
