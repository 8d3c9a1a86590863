"""The one reader of a stock ``lerobot-*`` script's command line, where such a script hands control to the plugin.

LeRobot's parser builds the env config inside ``draccus.parse`` of the whole pipeline config and hands it none of
its sibling fields, so the task a run uses (``--dataset.root`` of ``lerobot-train``, ``--policy.path`` of
``lerobot-eval``) is read here, once, when LeRobot's plugin discovery imports the plugin
(``registration.register_all``), and handed to the env config as a value. The config objects never read the
process's arguments. The one-line error hook (``errors.install_cli_excepthook``) reads them here too.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def stock_script() -> str | None:
    """This process's program name when it is a stock LeRobot script (``lerobot-train``, ``lerobot_eval.py`` ...,
    not ``lerobot-pnp``), else None."""
    prog = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    if not prog.startswith(("lerobot-", "lerobot_")) or prog == "lerobot-pnp":
        return None
    return prog


def task_source_from_argv() -> str | None:
    """``--dataset.root`` (lerobot-train) or ``--policy.path`` (lerobot-eval) from this process's arguments, else
    the same keys of the ``--config_path`` file (``lerobot-train --config_path configs/train_act_images.json``)."""
    from lerobot.configs.parser import parse_arg

    source = parse_arg("dataset.root") or parse_arg("policy.path")
    config_path = parse_arg("config_path")
    if source or not config_path or not Path(config_path).is_file():
        return source
    try:
        config = json.loads(Path(config_path).read_text())
    except (OSError, json.JSONDecodeError):
        return None  # LeRobot's parser reports a bad config file itself
    if not isinstance(config, dict):
        return None
    return (config.get("dataset") or {}).get("root") or (config.get("policy") or {}).get("path")


def dataset_roots_from_argv() -> list[str]:
    """Every ``--dataset.root`` value of this process's arguments (``--dataset.root=X`` or ``--dataset.root X``)."""
    roots = [a.split("=", 1)[1] for a in sys.argv if a.startswith("--dataset.root=")]
    return roots + [b for a, b in zip(sys.argv, sys.argv[1:], strict=False) if a == "--dataset.root"]
