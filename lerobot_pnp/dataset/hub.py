"""``lerobot-pnp push``: upload a generated dataset to the Hugging Face Hub with LeRobot's ``push_to_hub``."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from lerobot_pnp.dataset.validation import open_local_dataset
from lerobot_pnp.errors import DatasetError


@dataclass
class PushConfig:
    """``lerobot-pnp push``: upload a generated dataset to the Hugging Face Hub (tagged v3.0)."""

    repo_id: str = "local/baxter_pnp_keyframe"  # the Hub dataset repo (owner/name) to upload to
    root: str | None = None  # the dataset folder to upload; default outputs/datasets/<repo_id>
    private: bool = False  # create the Hub repo as private
    branch: str | None = None  # Hub branch to push to; none = main
    push_videos: bool = True  # also upload the videos/ folder (camera datasets)
    connect_timeout_s: float = 5.0  # fail fast when the Hub cannot be reached

    @property
    def output_root(self) -> Path:
        return Path(self.root) if self.root else Path("outputs/datasets") / self.repo_id


# What a LeRobotDataset is on the Hub: its folders, not the local bookkeeping beside them (the output folder's
# ``.pnp_manifest.json``, a study's ``stage.json``), which would make a downloaded copy look like a local command's
# own output
DATASET_FILES = ("meta/*", "data/*", "videos/*")


def push(cfg: PushConfig) -> dict:
    """Upload ``cfg.output_root`` to the Hub with LeRobot's ``push_to_hub`` (tags ``v3.0``).

    Fails fast, before anything is read for upload, when there is no token or the Hub cannot be reached.
    Never modifies the local folder.
    """
    from urllib.parse import urlparse

    root = cfg.output_root.resolve()
    ds = open_local_dataset(cfg.repo_id, root)  # validates the folder first
    from huggingface_hub import constants, get_token

    if constants.HF_HUB_OFFLINE:
        raise DatasetError("cannot push: HF_HUB_OFFLINE is set (unset it to upload)")
    if not get_token():
        raise DatasetError("cannot push: no Hugging Face token found; run `hf auth login` or set HF_TOKEN")
    url = urlparse(constants.ENDPOINT)
    host, port = url.hostname, url.port or (443 if url.scheme == "https" else 80)
    try:
        _connect(host, port, cfg.connect_timeout_s)
    except OSError as err:
        raise DatasetError(f"cannot push: the Hub at {constants.ENDPOINT} is unreachable ({err})") from None
    try:
        ds.push_to_hub(
            branch=cfg.branch, private=cfg.private, push_videos=cfg.push_videos, allow_patterns=list(DATASET_FILES)
        )
    except Exception as err:
        raise DatasetError(f"push to {cfg.repo_id} failed: {err}") from err
    return {
        "repo_id": cfg.repo_id,
        "root": str(root),
        "url": f"{constants.ENDPOINT}/datasets/{cfg.repo_id}",
        "tag": "v3.0",
    }


def _connect(host: str, port: int, timeout_s: float) -> None:
    """Open (and close) a TCP connection to ``host`` within ``timeout_s`` seconds, the name lookup included.

    ``socket.create_connection``'s timeout covers the connection only: behind a dead name server the resolver's
    own retries make a push without a network wait far longer than the timeout before it fails.
    """
    import socket
    import threading
    import time

    start, found = time.monotonic(), {}

    def lookup() -> None:
        try:
            found["addresses"] = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
        except OSError as err:
            found["error"] = err

    resolver = threading.Thread(target=lookup, daemon=True)  # a lookup cannot be cancelled: left to finish alone
    resolver.start()
    resolver.join(timeout_s)
    if resolver.is_alive():
        raise TimeoutError(f"no answer to the name lookup of {host} within {timeout_s:g} s")
    if "error" in found:
        raise found["error"]
    left = max(timeout_s - (time.monotonic() - start), 0.1)
    *_, address = found["addresses"][0]
    with socket.create_connection(address[:2], timeout=left):
        pass
