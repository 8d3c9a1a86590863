"""Episode counts and batch sizes across the documented commands.

An episode count has two spellings: ``--num_episodes`` for the episodes of data a command records or reads,
``--n_episodes`` for the episodes it runs (as ``lerobot-eval --eval.n_episodes``); ``cli.RENAMED_OPTIONS`` turns
an older spelling into a one-line error that names the current one. The command-line reference has one table that
names each command's (``scripts/docs_reference.py`` ``episode-flags``), and it lists every integer episode count a
command has. Every
documented ``lerobot-eval`` run uses the studies' batch of 50 environments: the batch size can flip a borderline
episode, so another one would not reproduce the published numbers.
"""

from __future__ import annotations

import dataclasses
import re
import typing

from clis import load_script
from test_docs_commands import documented_commands

STUDY_BATCH = "50"


def _flag_value(argv: list[str], flag: str) -> str | None:
    for i, arg in enumerate(argv):
        if arg == flag and i + 1 < len(argv):
            return argv[i + 1]
        if arg.startswith(flag + "="):
            return arg.split("=", 1)[1]
    return None


def eval_runs_off_the_study_batch(commands) -> list[str]:
    """The documented ``lerobot-eval`` runs (a policy and an env named, not an elided ``...``) whose
    ``--eval.batch_size`` is missing or not the studies'."""
    out = []
    for c in commands:
        runs = c.argv[0] == "lerobot-eval" and "..." not in c.argv
        runs = runs and _flag_value(c.argv, "--policy.path") and _flag_value(c.argv, "--env.type")
        if runs and _flag_value(c.argv, "--eval.batch_size") != STUDY_BATCH:
            out.append(str(c))
    return out


def test_every_documented_lerobot_eval_run_uses_the_studies_batch():
    commands = [c for c in documented_commands() if not c.where.startswith("docs/changelog.md")]
    assert sum(c.argv[0] == "lerobot-eval" for c in commands) >= 10
    assert eval_runs_off_the_study_batch(commands) == []


def test_a_run_off_the_batch_is_found():
    from test_docs_commands import Command

    runs = [Command("a.md:1", ["lerobot-eval", "--policy.path=p", "--env.type=baxter_pnp"]),
            Command("a.md:2", ["lerobot-eval", "--policy.path", "p", "--env.type", "x", "--eval.batch_size", "10"]),
            Command("a.md:3", ["lerobot-eval", "--policy.path", "p", "--env.type", "x", "--eval.batch_size=50"]),
            Command("a.md:4", ["lerobot-eval", "...", "--env.nudge_max", "0.03"])]  # fmt: skip
    assert [r.split(":")[1] for r in eval_runs_off_the_study_batch(runs)] == ["1", "2"]


def test_the_reference_table_names_every_episode_count_of_every_command():
    from lerobot_pnp import cli

    load_script("scripts/docs_tables.py")  # puts scripts/ on the path
    import docs_reference

    listed = {(command, name) for command, names in docs_reference.EPISODE_FLAGS for name in names}
    counts = set()
    for name, (ref, _, _) in cli.COMMANDS.items():
        cls = cli._load(ref)
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if re.search(r"episodes|rollouts|demos", f.name) and int in typing.get_args(hints[f.name]) + (
                hints[f.name],
            ):
                counts.add((f"lerobot-pnp {name}", f.name))
    assert counts - listed == set(), "add these to docs_reference.EPISODE_FLAGS"
    table = docs_reference.episode_flags("")
    assert "| `lerobot-eval` | `--eval.n_episodes` |" in table and "| `lerobot-pnp viz` | `--n_episodes` |" in table


# counts of another thing than a command's episodes: a sub-count of the episodes run, the rollouts of a round
OTHER_COUNTS = {"cli_check_episodes", "rollouts_per_round"}


def test_every_episode_count_is_num_episodes_or_n_episodes():
    load_script("scripts/docs_tables.py")  # puts scripts/ on the path
    import docs_reference

    names = {name for _, fields in docs_reference.EPISODE_FLAGS for name in fields}
    assert names - OTHER_COUNTS == {"num_episodes", "n_episodes"}


def test_a_renamed_episode_flag_is_one_line_naming_its_spelling(capsys, tmp_path):
    from lerobot_pnp import cli

    assert cli.main(["dagger", "--num_demos", "3", f"--output_dir={tmp_path / 'd'}"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("lerobot-pnp dagger: error: --num_demos is spelled --num_episodes") and "\n" not in err
    config = tmp_path / "viz.json"
    config.write_text('{"n_rollouts": 2}')
    assert cli.main(["viz", f"--config_path={config}"]) == 2
    assert f"--n_rollouts in {config} is spelled --n_episodes" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()  # refused before anything was written
