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


BLOCKS = {"presets": presets_table, "suite-catalogue": suite_catalogue, "cli-help": cli_help, "env-fields": env_fields,
          "policy-fields": policy_fields, "pixels-fields": pixels_fields}  # fmt: skip
