"""The one reader of a stock ``lerobot-*`` script's command line, where such a script hands control to the plugin.

LeRobot's parser builds the env config inside ``draccus.parse`` of the whole pipeline config and hands it none of
its sibling fields, so the task a run uses (``--dataset.root`` of ``lerobot-train``, ``--policy.path`` of
``lerobot-eval``) is read here, once, when LeRobot's env configs are loaded (``registration``), and the task it records is
handed to the env config as a value. The config objects never read the process's arguments.

``run_is_ours`` decides whether the plugin's hooks and messages have any business in this process: LeRobot
imports the plugin in every ``lerobot-*`` process, and a run on another env, policy and dataset must see
nothing of it. It reads the arguments, the ``--config_path`` file and the small JSON files of the folders they
name; nothing heavier.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

from huggingface_hub import hf_hub_download
from huggingface_hub.errors import EntryNotFoundError, HfHubHTTPError

from lerobot_pnp.presets import ENV_TYPE
from lerobot_pnp.sim.recorded_files import CHECKPOINT_RECORDED_FILE, RECORDED_FILE

# the policy types our configuration modules register (they load LeRobot's configs)
POLICY_TYPES = ("pnp_lstm", "pnp_pixels")


def stock_script() -> str | None:
    """This process's program name when it is a stock LeRobot script (``lerobot-train``, ``lerobot_eval.py`` ...,
    not ``lerobot-pnp``), else None."""
    prog = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    if not prog.startswith(("lerobot-", "lerobot_")) or prog == "lerobot-pnp":
        return None
    return prog


def arg(name: str, args: list[str] | None = None) -> str | None:
    """The last value of ``--name`` in ``args`` (default: this process's), as ``--name=value`` or ``--name value``."""
    args = sys.argv[1:] if args is None else args
    found = None
    for index, item in enumerate(args):
        if item.startswith(f"--{name}="):
            found = item.split("=", 1)[1]
        elif item == f"--{name}" and index + 1 < len(args) and not args[index + 1].startswith("--"):
            found = args[index + 1]
    return found


def _config_file() -> dict:
    """The ``--config_path`` file of this process's arguments as a dict ({} when absent or unreadable: LeRobot's
    parser reports a bad one itself)."""
    path = arg("config_path")
    if not path or not Path(path).is_file():
        return {}
    try:
        config = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return {}
    return config if isinstance(config, dict) else {}


def _section(config: dict, name: str) -> dict:
    value = config.get(name)
    return value if isinstance(value, dict) else {}


def task_source_from_argv() -> str | None:
    """``--dataset.root`` (lerobot-train) or ``--policy.path`` (lerobot-eval) from this process's arguments, else
    the same keys of the ``--config_path`` file (``lerobot-train --config_path configs/train_act_images.json``)."""
    source = arg("dataset.root") or arg("policy.path")
    if source or not arg("config_path"):
        return source
    config = _config_file()
    return _section(config, "dataset").get("root") or _section(config, "policy").get("path")


def names_our_env() -> bool:
    """Whether this process's arguments (or its ``--config_path`` file) name ``--env.type=baxter_pnp``."""
    return (arg("env.type") or _section(_config_file(), "env").get("type")) == ENV_TYPE


# a Hub repo id as LeRobot takes one for ``--policy.path``: ``owner/name``, when no such folder exists
_REPO_ID = re.compile(r"^[\w.-]+/[\w.-]+$")


def hub_checkpoint_folder(source: str) -> str | None:
    """The local folder (in the Hub cache) holding the task record of the checkpoint that the repo id ``source``
    names, downloaded as LeRobot downloads the checkpoint's other files; None when ``source`` is a path, when the
    repository records no task, or when it cannot be reached (LeRobot then reports the repository itself)."""
    if not _REPO_ID.match(source) or Path(source).expanduser().exists():
        return None
    try:
        return str(Path(hf_hub_download(repo_id=source, filename=CHECKPOINT_RECORDED_FILE)).parent)
    except (EntryNotFoundError, HfHubHTTPError, OSError, ValueError):  # not found, unreachable, offline and not cached
        return None


def command_line_sources() -> dict[str | None, str | None]:
    """The task sources this process's arguments name, as ``BaxterPnPEnvConfig.read_edge_records`` takes them:
    the default source (None: ``task_source_from_argv``) and an explicit ``--env.task_source``. A ``--policy.path``
    that is a Hub repo id, in a run on this env, stands for the checkpoint's task record fetched from the Hub."""
    default = task_source_from_argv()
    if default and default == arg("policy.path") and names_our_env():
        default = hub_checkpoint_folder(default) or default
    sources: dict[str | None, str | None] = {None: default}
    explicit = arg("env.task_source") or _section(_config_file(), "env").get("task_source")
    if isinstance(explicit, str) and explicit:
        sources[explicit] = explicit
    return sources


def dataset_roots_from_argv() -> list[str]:
    """Every ``--dataset.root`` value of this process's arguments (``--dataset.root=X`` or ``--dataset.root X``)."""
    roots = [a.split("=", 1)[1] for a in sys.argv if a.startswith("--dataset.root=")]
    return roots + [b for a, b in zip(sys.argv, sys.argv[1:], strict=False) if a == "--dataset.root"]


def run_is_ours() -> bool:
    """Whether this process's run involves our env, our policy or our data: ``--env.type=baxter_pnp``,
    ``--policy.type=pnp_lstm`` (on the command line or in its ``--config_path`` file), or a dataset / checkpoint
    folder it names (``--dataset.root``, ``--policy.path``, ``--dataset.repo_id`` in LeRobot's cache) that records
    our task or holds a ``pnp_lstm`` checkpoint."""
    config = _config_file()
    env_type = arg("env.type") or _section(config, "env").get("type")
    policy_type = arg("policy.type") or _section(config, "policy").get("type")
    if env_type == ENV_TYPE or policy_type in POLICY_TYPES:
        return True
    folders = [task_source_from_argv(), *dataset_roots_from_argv(), arg("policy.path")]
    repo_id = arg("dataset.repo_id") or _section(config, "dataset").get("repo_id")
    if repo_id and isinstance(repo_id, str):
        from lerobot.utils.constants import HF_LEROBOT_HOME

        folders.append(str(HF_LEROBOT_HOME / repo_id))
    if arg("config_path"):
        folders.append(str(Path(arg("config_path")).parent))  # --resume: <checkpoint>/pretrained_model/...
    return any(is_our_folder(Path(f).expanduser()) for f in folders if isinstance(f, str) and f)


def is_our_folder(folder: Path) -> bool:
    """A dataset that records our task, or a checkpoint (``pretrained_model``, step or run folder) of our env or
    policy."""
    try:
        if any((folder / name).is_file() for name in (RECORDED_FILE, CHECKPOINT_RECORDED_FILE)):
            return True
        for candidate in (folder, folder / "pretrained_model", folder / "checkpoints/last/pretrained_model"):
            for name, key in (("config.json", None), ("train_config.json", "policy"), ("train_config.json", "env")):
                if (candidate / name).is_file() and _names_ours(candidate / name, key):
                    return True
    except OSError:
        return False
    return False


def _names_ours(path: Path, key: str | None) -> bool:
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False
    section = (data.get(key) if key else data) if isinstance(data, dict) else None
    return isinstance(section, dict) and section.get("type") in (ENV_TYPE, *POLICY_TYPES)
