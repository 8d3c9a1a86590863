"""``lerobot-pnp``: a thin command-line face over the library. It parses and prints, nothing else.

Each sub-command is a config dataclass (defaults in the dataclass, a JSON/YAML file via ``--config_path``,
flags override) and a library function taking it. The function returns a summary dict that is printed.
"""

from __future__ import annotations

import errno
import importlib
import itertools
import json
import signal
import sys
import tempfile
import typing
from pathlib import Path

from lerobot_pnp.support.cli_config import expand_home, layered_config_file

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
        "fast in-memory training of pnp_lstm or pnp_pixels (same checkpoint layout as lerobot-train)",
    ),
    "viz": (
        "lerobot_pnp.viz:VizConfig",
        "lerobot_pnp.viz:visualize",
        "inspect episodes or policy rollouts in Rerun (viewer, --save rec.rrd, or --screenshot shot.png)",
    ),
    "expert": (
        "lerobot_pnp.evaluation.expert_eval:ExpertEvalConfig",
        "lerobot_pnp.evaluation.expert_eval:evaluate_expert",
        "run the scripted expert on seeded episodes or on lerobot-eval's suites: success, failures by cause",
    ),
    "lookup-table": (
        "lerobot_pnp.report.baselines:LookupTableCheckpointConfig",
        "lerobot_pnp.report.baselines:write_lookup_table",
        "write the lookup-table baseline over a dataset's training episodes as a checkpoint lerobot-eval loads",
    ),
    "dagger": (
        "lerobot_pnp.dagger:DaggerConfig",
        "lerobot_pnp.dagger:run_dagger",
        "DAgger rounds with the expert as teacher",
    ),
    "demo": (
        "lerobot_pnp.demo:DemoConfig",
        "lerobot_pnp.demo:run_demo",
        "end to end: generate, train, evaluate, write report.md (the README's main job; --quick, --full)",
    ),
    "report": (
        "lerobot_pnp.report.run:StudyConfig",
        "lerobot_pnp.report.run:run_study",
        "the reproduction study (methods x suites x seeds -> report.md; --full: the paper-task study; resumable)",
    ),
    "compare": (
        "lerobot_pnp.evaluation.compare:CompareConfig",
        "lerobot_pnp.evaluation.compare:run_compare",
        "compare lerobot-eval runs (RUN or NAME=RUN1,RUN2 ...): intervals, control arm, paired verdicts",
    ),
    "leaderboard": (
        "lerobot_pnp.evaluation.leaderboard:LeaderboardConfig",
        "lerobot_pnp.evaluation.leaderboard:write_leaderboard",
        "regenerate docs/leaderboard.md from the committed lerobot-eval outputs of the held-out protocol",
    ),
}


# Episode counts have two names: ``num_episodes``, the episodes of data a command records or reads (as
# ``lerobot-record --dataset.num_episodes``), and ``n_episodes``, the episodes it runs (as ``lerobot-eval
# --eval.n_episodes``). Options once spelled otherwise get a one-line error naming their current spelling.
RENAMED_OPTIONS: dict[str, dict[str, str]] = {
    "dagger": {"num_demos": "num_episodes", "eval_episodes": "n_episodes"},
    "lookup-table": {"n_episodes": "num_episodes"},
    "viz": {"n_rollouts": "n_episodes"},
    "leaderboard": {"episodes": "n_episodes"},
}


def check_renamed(name: str, config_path: str | None, args: list[str]) -> None:
    """Raise ``ConfigError`` naming the current spelling when ``args`` or the ``--config_path`` file (its top
    level) use a renamed option of command ``name``."""
    from lerobot_pnp.errors import ConfigError

    renamed = RENAMED_OPTIONS.get(name, {})
    used = [a[2:].split("=", 1)[0].replace("-", "_") for a in args if a.startswith("--")]
    try:
        keys = list(json.loads(Path(config_path).read_text())) if config_path else []
    except (OSError, ValueError, TypeError):
        keys = []  # not JSON (YAML) or unreadable: the parser reports what it rejects
    for where, option in [("", o) for o in used] + [(f" in {config_path}", k) for k in keys]:
        if option in renamed:
            raise ConfigError(
                f"--{option}{where} is spelled --{renamed[option]} (num_episodes: episodes of data recorded or "
                "read; n_episodes: episodes run)"
            )


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
    width = max(map(len, COMMANDS))
    lines += [f"  {name:<{width}} {help_}" for name, (_, _, help_) in COMMANDS.items()]
    lines += ["", "`lerobot-pnp <command> --help` lists a command's options."]
    return "\n".join(lines)


def _split_config_path(args: list[str]) -> tuple[str | None, list[str]]:
    """Take ``--config_path FILE`` / ``--config_path=FILE`` out of ``args``."""
    from lerobot_pnp.errors import ConfigError

    for i, arg in enumerate(args):
        if arg == "--config_path" or arg.startswith("--config_path="):
            if "=" in arg:
                value, rest = arg.split("=", 1)[1], args[:i] + args[i + 1 :]
            elif i + 1 < len(args) and not args[i + 1].startswith("--"):
                value, rest = args[i + 1], args[:i] + args[i + 2 :]
            else:
                value, rest = "", args
            if not value:
                raise ConfigError("--config_path needs a file (a JSON or YAML config, e.g. configs/demo.json)")
            if not Path(value).is_file():
                raise ConfigError(f"--config_path {value!r}: no such file")
            return value, rest
    return None, args


def command_config(name: str, args: list[str]) -> tuple[type, str | None, list[str]]:
    """Command ``name``'s config class (chosen by its input where it has ``command_class``), its ``--config_path``
    and the remaining arguments, with ``~`` expanded in every value (``cli_config.expand_home``)."""
    config_cls = _load(COMMANDS[name][0])
    args = expand_home(args)
    if name == "compare":  # its runs are positional: RUN_A RUN_B ...
        args = _load("lerobot_pnp.evaluation.compare:positional_runs")(args)
    config_path, args = _split_config_path(args)
    check_renamed(name, config_path, args)
    if hasattr(config_cls, "command_class"):  # a config class chosen by the input (train: the policy type)
        config_cls, args = config_cls.command_class(config_path, args)
    return config_cls, config_path, args


def parse_config(config_cls: type, config_path: str | None, args: list[str]):
    """The config: ``config_cls``'s defaults (its nested default factories' values included), then the
    ``--config_path`` file, then the flags (``cli_config``). Raises draccus's errors for a value it rejects."""
    import draccus

    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    args = normalize_args(config_cls, args)
    records = BaxterPnPEnvConfig.read_edge_records({s: s for s in env_task_sources(config_path, args)})
    with tempfile.TemporaryDirectory(prefix="lerobot_pnp_cfg_") as tmp:
        layered = layered_config_file(config_cls, config_path, args, tmp)
        with BaxterPnPEnvConfig.reading_edge_records(records):  # the edge: records read here, not by the configs
            return draccus.parse(config_class=config_cls, config_path=layered, args=args)


def env_task_sources(config_path: str | None, args: list[str]) -> list[str]:
    """The ``task_source`` values of the env configs a command line names (``--env.task_source`` flags, the
    ``env`` section of its ``--config_path`` file)."""
    sources = [
        a.split("=", 1)[1] for a in args if a.startswith("--") and a.split("=", 1)[0].endswith("env.task_source")
    ]
    sources += [b for a, b in itertools.pairwise(args) if a.startswith("--") and a.endswith("env.task_source")]
    try:
        env = json.loads(Path(config_path).read_text()).get("env") if config_path else None
    except (OSError, ValueError, AttributeError):
        env = None
    if isinstance(env, dict) and isinstance(env.get("task_source"), str):
        sources.append(env["task_source"])
    return [s for s in sources if s]


def config_of(name: str, args: list[str]):
    """Command ``name``'s config as ``lerobot-pnp name ARGS`` builds it (without running the command)."""
    return parse_config(*command_config(name, args))


def _os_error_line(err: OSError, name: str) -> str:
    """One line for an operating-system failure (disk full, read-only, permission), with what to do next."""
    what = {errno.ENOSPC: "disk full", errno.EROFS: "read-only file system", errno.EACCES: "permission denied"}
    reason = what.get(err.errno, err.strerror or type(err).__name__)
    where = f" at {err.filename}" if err.filename else ""
    hint = (
        " (free space or fix the folder, then rerun with --resume: finished work is kept)" if name == "generate" else ""
    )
    return f"lerobot-pnp {name}: {reason}{where}{hint}"


def _sigterm_as_interrupt(signum, frame):
    """The first SIGTERM unwinds like Ctrl-C (one line, exit 2, finished work kept); a second one while that
    unwinding joins worker processes terminates at once, instead of a traceback from the interpreter's exit hooks."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    """Parse, run, print. Any ``PnPError`` (the package's error tree) or operational failure is one line, exit 2."""
    import draccus

    from lerobot_pnp.errors import PnPError, one_line
    from lerobot_pnp.integration.registration import register_all

    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0
    name, args = argv[0], argv[1:]
    if name not in COMMANDS:
        print(f"lerobot-pnp: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    signal.signal(signal.SIGTERM, _sigterm_as_interrupt)
    _, func_ref, summary = COMMANDS[name]
    register_all()
    try:
        func = _load(func_ref)
        config_cls, config_path, args = command_config(name, args)
        if "-h" in args or "--help" in args:  # the options of the class chosen (train: of its policy type)
            from lerobot_pnp.support.cli_help import command_help

            print(command_help(name, summary, config_cls))
            return 0
        try:
            cfg = parse_config(config_cls, config_path, args)
        except (draccus.utils.ParsingError, ValueError, TypeError, OverflowError) as err:
            # a config dataclass rejected a value (its message names the field), or a value has the wrong type
            cause = err.__cause__ if isinstance(err.__cause__, PnPError) else err
            print(f"lerobot-pnp {name}: invalid configuration: {one_line(cause)}", file=sys.stderr)
            return 2
        result = func(cfg)
    except PnPError as err:
        print(f"lerobot-pnp {name}: error: {one_line(err)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        hint = " (rerun with --resume to continue)" if name == "generate" else ""
        print(f"\nlerobot-pnp {name}: interrupted{hint}", file=sys.stderr)
        return 2
    except OSError as err:
        print(_os_error_line(err, name), file=sys.stderr)
        return 2
    if hasattr(result, "summary"):
        result = result.summary()
    if result is not None:
        print(json.dumps(result, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
