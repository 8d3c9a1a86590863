"""``lerobot-pnp``: a thin command-line face over the library. It parses and prints, nothing else.

Each sub-command is a config dataclass (defaults in the dataclass, a JSON/YAML file via ``--config_path``,
flags override) and a library function taking it. The function returns a summary dict that is printed.
"""

from __future__ import annotations

import importlib
import json
import sys
import typing

# name -> ("module:ConfigClass", "module:function", help)
COMMANDS: dict[str, tuple[str, str, str]] = {
    "generate": (
        "lerobot_pnp.dataset:GenerateConfig",
        "lerobot_pnp.dataset:generate",
        "generate expert demonstrations as a LeRobotDataset v3",
    ),
    "push": ("lerobot_pnp.dataset:PushConfig", "lerobot_pnp.dataset:push", "upload a dataset to the Hugging Face Hub"),
    "train": (
        "lerobot_pnp.train_fast:TrainFastConfig",
        "lerobot_pnp.train_fast:train_fast",
        "fast in-memory training of the pnp_lstm policy (same checkpoint layout as lerobot-train)",
    ),
    "viz": (
        "lerobot_pnp.viz:VizConfig",
        "lerobot_pnp.viz:visualize",
        "inspect episodes or policy rollouts in Rerun (viewer, --save rec.rrd, or --screenshot shot.png)",
    ),
    "expert": (
        "lerobot_pnp.expert_eval:ExpertEvalConfig",
        "lerobot_pnp.expert_eval:evaluate_expert",
        "run the scripted expert on seeded episodes and report success and failures by cause",
    ),
    "demo": (
        "lerobot_pnp.demo:DemoConfig",
        "lerobot_pnp.demo:run_demo",
        "end to end: generate, train, evaluate (the README's main job)",
    ),
}


def _load(ref: str):
    module, name = ref.split(":")
    return getattr(importlib.import_module(module), name)


_BOOL_WORDS = ("true", "false", "1", "0", "yes", "no")


def normalize_args(config_cls, args: list[str]) -> list[str]:
    """Accept the usual command-line spellings before draccus parses them, for every command alike.

    ``--repo-id`` -> ``--repo_id``; a bare ``--resume`` for a bool field -> ``--resume=true``; several values
    after a list field (``--episode-index 0 1``) -> ``--episode_index=[0,1]``. Field types come from the
    command's config dataclass; nested fields (``--policy.path``) keep draccus's own syntax.
    """
    hints = typing.get_type_hints(config_cls)
    bool_fields = {name for name, tp in hints.items() if tp is bool}
    list_fields = {name for name, tp in hints.items() if "list[" in str(tp)}
    out: list[str] = []
    i = 0
    while i < len(args):
        arg = args[i]
        if not arg.startswith("--"):
            out.append(arg)
            i += 1
            continue
        name, eq, val = arg[2:].partition("=")
        name = name.replace("-", "_")
        following = []
        while not eq and i + 1 + len(following) < len(args) and not args[i + 1 + len(following)].startswith("--"):
            following.append(args[i + 1 + len(following)])
        if not eq and name in bool_fields and not (following and following[0].lower() in _BOOL_WORDS):
            out.append(f"--{name}=true")
        elif not eq and name in list_fields and following and "[" not in following[0]:
            out.append(f"--{name}=[{','.join(v for f in following for v in f.replace(',', ' ').split())}]")
            i += len(following)
        else:
            out.append(f"--{name}{eq}{val}")
        i += 1
    return out


def _usage() -> str:
    lines = ["usage: lerobot-pnp <command> [--config_path FILE] [--field value ...]", "", "commands:"]
    lines += [f"  {name:<10} {help_}" for name, (_, _, help_) in COMMANDS.items()]
    lines += ["", "`lerobot-pnp <command> --help` lists a command's options."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    import draccus

    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0
    name, args = argv[0], argv[1:]
    if name not in COMMANDS:
        print(f"lerobot-pnp: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    config_ref, func_ref, _ = COMMANDS[name]
    config_cls, func = _load(config_ref), _load(func_ref)
    config_path = None
    for i, arg in enumerate(args):
        if arg.startswith("--config_path"):
            config_path = arg.split("=", 1)[1] if "=" in arg else args[i + 1]
            args = args[:i] + args[i + (1 if "=" in arg else 2) :]
            break
    args = normalize_args(config_cls, args)
    from lerobot_pnp.errors import PnPError

    try:
        cfg = draccus.parse(config_class=config_cls, config_path=config_path, args=args)
    except (PnPError, draccus.utils.ParsingError, ValueError, TypeError, FileNotFoundError) as err:
        # a config dataclass rejected a value (its message names the field), or the config file is unreadable
        cause = err.__cause__ if isinstance(err.__cause__, PnPError) else err
        print(f"lerobot-pnp {name}: invalid configuration: {cause}", file=sys.stderr)
        return 2
    try:
        result = func(cfg)
    except PnPError as err:
        print(f"lerobot-pnp {name}: error: {err}", file=sys.stderr)
        return 1
    if hasattr(result, "summary"):
        result = result.summary()
    if result is not None:
        print(json.dumps(result, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
