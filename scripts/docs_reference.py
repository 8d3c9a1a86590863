"""The reference blocks of README.md and docs/, read from the code itself: the task presets, the suite catalogue,
every command's ``--help`` and the config dataclasses' fields (``scripts/docs_tables.py`` renders them).

A page's reference table is what the code says today: the CLI's help text, a field's comment on its dataclass and
its default come from the same places ``--help`` reads them.
"""

from __future__ import annotations

import os
from unittest import mock


def _changes(changes: dict, base: dict) -> str:
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        if isinstance(v, (tuple, list)):
            return "(" + ", ".join(fmt(x) for x in v) + ")"
        return str(v)

    shown = {k: v for k, v in changes.items() if k not in base or fmt(base[k]) != fmt(v)}
    return ", ".join(f"`{k}={fmt(v)}`" for k, v in shown.items()) or "none"


def presets_table(base: str) -> str:
    """The task fields where the two presets differ, with each preset's value and the field's description."""
    from lerobot_pnp.presets import FULL_TASK, PAPER_TASK
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.support.cli_help import field_doc

    lines = ["| field | `paper` | `full` | what it is |", "|---|---|---|---|"]
    for k, v in FULL_TASK.items():
        if PAPER_TASK[k] != v:
            doc = field_doc(BaxterPnPEnvConfig, k).split(". ")[0].replace("|", "\\|")
            lines.append(f"| `{k}` | {_changes({k: PAPER_TASK[k]}, {})[len(k) + 2 : -1]} | "
                         f"{_changes({k: v}, {})[len(k) + 2 : -1]} | {doc} |")  # fmt: skip
    same = sum(PAPER_TASK[k] == v for k, v in FULL_TASK.items())
    return "\n".join([*lines, "", f"The other {same} task fields are the same in both presets."])


def suite_catalogue(base: str) -> str:
    """Every suite of ``sim/suites.py``, grouped as the studies use them, with what it changes."""
    from lerobot_pnp.presets import FULL_TASK, PAPER_TASK, VISUAL_TRAINING
    from lerobot_pnp.sim.suites import ALL_AXES, SUITES
    from lerobot_pnp.sim.visual_suites import VISUAL_SUITES

    groups = {
        "The paper-task study (base: the task a policy was trained on)": [],
        "The held-out protocol (base: the `full` task)": [],
        "DAgger's suites (`quiet*`: every perturbation off, then one at a time)": [],
        "The visual axes (`train_visual`: changes from the `paper` task; the others: from `train_visual`)": [],
    }
    titles = list(groups)
    for s in SUITES.values():
        key = 3 if s.name in VISUAL_SUITES else 1 if s.name.startswith(("train_", "heldout_")) else 2 if (
            s.name.startswith("quiet")) else 0  # fmt: skip
        groups[titles[key]].append(s)
    out = [
        f"{len(SUITES)} suites. Changes shown: every field a paper-task suite sets; for the held-out protocol's and "
        "DAgger's suites, the fields whose value differs from the `full` preset (their base); for the visual "
        "suites, as their group says."
    ]
    for i, (title, suites) in enumerate(groups.items()):
        out += ["", f"### {title}", "", "| suite | what it is | env-config changes |", "|---|---|---|"]
        for s in suites:
            ref = {} if i == 0 else FULL_TASK if i < 3 else PAPER_TASK if s.name == "train_visual" else (
                {**FULL_TASK, **VISUAL_TRAINING})  # fmt: skip
            changes = "; ".join(_changes(p, ref) for p in s.parts)
            out.append(f"| `{s.name}` | {s.description} | {changes} |")
    out += ["", "### Held-out axes", "", "| axis | what varies | in distribution | held out |", "|---|---|---|---|"]
    for a in ALL_AXES:
        ins, held = (", ".join(f"`{n}`" for n in names) for names in (a.in_distribution, a.held_out))
        out.append(f"| {a.name} | {a.description} | {ins} | {held} |")
    return "\n".join(out)


def cli_help(base: str) -> str:
    """``lerobot-pnp --help`` and every command's ``--help``, as the CLI prints them at 100 columns."""
    from lerobot_pnp import cli
    from lerobot_pnp.support.cli_help import command_help

    with mock.patch.dict(os.environ, {"COLUMNS": "100"}):
        out = ["```text", "$ lerobot-pnp --help", cli._usage(), "```"]
        for name, (cfg_ref, _, summary) in cli.COMMANDS.items():
            out += [
                "",
                f"### `lerobot-pnp {name}`",
                "",
                "```text",
                command_help(name, summary, cli._load(cfg_ref)),
                "```",
            ]
    return "\n".join(out)


def _field_table(cls, prefix: str) -> str:
    from lerobot_pnp.support.cli_help import field_rows

    lines = ["| flag | type | description [default] |", "|---|---|---|"]
    for flag, tp, text in field_rows(cls):
        text = text.replace("\N{NO-BREAK SPACE}", " ").replace("|", "\\|")
        lines.append(f"| `{prefix}{flag.removeprefix('--')}` | `{tp}` | {text} |")
    return "\n".join(lines)


def env_fields(base: str) -> str:
    """Every field of the env config: flags of lerobot-eval, lerobot-train and lerobot-pnp (``--env.*``)."""
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    return _field_table(BaxterPnPEnvConfig, "--env.")


def policy_fields(base: str) -> str:
    """Every field of the pnp_lstm policy config (``--policy.*``)."""
    from lerobot_pnp.policy.configuration_pnp_lstm import PnpLstmConfig

    return _field_table(PnpLstmConfig, "--policy.")


def pixels_fields(base: str) -> str:
    """The fields ``pnp_pixels`` adds to ``pnp_lstm``'s, and those whose default it changes (``--policy.*``)."""
    from lerobot_pnp.policy.configuration_pnp_lstm import PnpLstmConfig
    from lerobot_pnp.policy.configuration_pnp_pixels import PnpPixelsConfig
    from lerobot_pnp.support.cli_help import field_rows

    lstm = {flag: text for flag, _, text in field_rows(PnpLstmConfig)}
    rows = [(f, tp, text) for f, tp, text in field_rows(PnpPixelsConfig) if lstm.get(f) != text]
    lines = ["| flag | type | description [default] |", "|---|---|---|"]
    for flag, tp, text in rows:
        text = text.replace("\N{NO-BREAK SPACE}", " ").replace("|", "\\|")
        lines.append(f"| `--policy.{flag.removeprefix('--')}` | `{tp}` | {text} |")
    return "\n".join(lines)


# each command's episode counts: (command, [field, ...]); the fields are read back from the command's config class
# (cli.COMMANDS; lerobot-eval: LeRobot's EvalConfig), so a renamed field fails the render, not the reader
EPISODE_FLAGS = (
    ("lerobot-pnp generate", ["num_episodes"]),
    ("lerobot-pnp demo", ["num_episodes", "cli_check_episodes"]),
    ("lerobot-pnp report", ["num_episodes", "cli_check_episodes"]),
    ("lerobot-pnp dagger", ["num_episodes", "rollouts_per_round", "n_episodes"]),
    ("lerobot-pnp lookup-table", ["num_episodes"]),
    ("lerobot-pnp expert", ["n_episodes"]),
    ("lerobot-eval", ["n_episodes"]),
    ("lerobot-pnp viz", ["n_episodes"]),
    ("lerobot-pnp leaderboard", ["n_episodes"]),
)


# what LeRobot's own field means here, where LeRobot's code gives it no description
STOCK_DOCS = {("lerobot-eval", "n_episodes"): "episodes to run, per suite when `--env.task` names several"}


def _config_class(command: str):
    from lerobot_pnp import cli

    if command == "lerobot-eval":
        from lerobot.configs.default import EvalConfig

        return EvalConfig
    return cli._load(cli.COMMANDS[command.removeprefix("lerobot-pnp ")][0])


def episode_flags(base: str) -> str:
    """Which flag sets an episode count on each command: the names differ from command to command (LeRobot's own
    ``--eval.n_episodes`` among them), so one table names them all, each with its field's own description."""
    import dataclasses
    import re
    from pathlib import Path

    from lerobot_pnp.support.cli_help import field_doc

    lines = ["| command | flag | what it counts |", "|---|---|---|"]
    for command, names in EPISODE_FLAGS:
        cls = _config_class(command)
        fields = {f.name for f in dataclasses.fields(cls)}
        for name in names:
            if name not in fields:
                raise SystemExit(f"{command}: no field {name!r} in {cls.__name__} (docs_reference.EPISODE_FLAGS)")
            flag = f"--eval.{name}" if command == "lerobot-eval" else f"--{name}"
            doc = field_doc(cls, name) or STOCK_DOCS[(command, name)]
            doc = re.split(r"\.\s+(?=[A-Z])", re.sub(r"\s+", " ", doc))[0].rstrip(".").replace("``", "`")
            doc = doc.replace("|", "\\|")
            lines.append(f"| `{command}` | `{flag}` | {doc} |")
    root = Path(__file__).resolve().parents[1]
    scripts = {}
    for path in sorted([*root.glob("benchmarks/*.py"), *root.glob("scripts/*.py")]):
        for flag in re.findall(r"add_argument\([\"'](--(?:num|n)_episodes)[\"']", path.read_text()):
            scripts.setdefault(flag, []).append(f"`{path.relative_to(root)}`")
    what = {"--num_episodes": "the episodes the script generates", "--n_episodes": "the episodes the script runs "
            "(its `--help` says whether per suite, per run or per block)"}  # fmt: skip
    lines += [f"| {', '.join(paths)} | `{flag}` | {what[flag]} |" for flag, paths in sorted(scripts.items())]
    return "\n".join(
        [
            *lines,
            "",
            "`lerobot-pnp train` and `lerobot-train` train on every episode of the dataset's training split; "
            "`--test_episodes` (`lerobot-pnp train`) names the held-out range and `--dataset.episodes` "
            "(`lerobot-train`) a list of episodes to train on.",
        ]
    )


BLOCKS = {"episode-flags": episode_flags, "presets": presets_table, "suite-catalogue": suite_catalogue, "cli-help": cli_help, "env-fields": env_fields,
          "policy-fields": policy_fields, "pixels-fields": pixels_fields}  # fmt: skip
