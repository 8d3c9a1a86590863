"""The ``lerobot-pnp`` console script, and the real CLIs end to end on a tiny scale.

Fast tests call ``lerobot_pnp.cli.main([...])`` in-process (plus subprocess calls of the installed script);
the end-to-end chain through the real ``lerobot-eval`` is in test_cli_end_to_end.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import zygote
from clis import ENV
from clis import exe as _exe
from clis import run as _run

from lerobot_pnp import cli


# ---------------------------------------------------------------------------------------------- fast
def test_help_lists_every_command(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in ("generate", "push", "train", "viz", "expert", "demo"):
        assert f"  {name} " in out, f"{name!r} missing from --help:\n{out}"
    assert cli.main([]) == 0  # no command: the same usage, not an error


def test_help_subprocess(tmp_path):
    proc = _run([_exe("lerobot-pnp"), "--help"], tmp_path, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "usage: lerobot-pnp" in proc.stdout and "generate" in proc.stdout


@pytest.mark.parametrize("name", list(cli.COMMANDS))
def test_command_help_documents_every_field(name, capsys):
    import dataclasses

    from lerobot_pnp.support.cli_help import field_rows

    assert cli.main([name, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: lerobot-pnp {name}")
    config_cls = cli._load(cli.COMMANDS[name][0])
    flags = [flag for flag, _, _ in field_rows(config_cls)]
    assert flags and len(flags) == len(set(flags)), "a flag is listed twice"
    for field in dataclasses.fields(config_cls):
        assert f"--{field.name} " in out or f"--{field.name}." in out, f"--{field.name} missing"
    assert "def __post_init__" not in out and "--policy str" not in out


def _help_entries(text: str) -> dict[str, str]:
    """``--flag`` -> its description (default included) parsed from a ``lerobot-pnp <command> --help`` text."""
    entries: dict[str, str] = {}
    flag = None
    lines = text.rstrip("\n").split("\n")
    for line in lines[lines.index("options:") + 1 :]:
        if line.startswith("  --"):
            head, _, body = line[2:].partition("  ")  # flag and type use single spaces; the column gap is >= 2
            flag = head.split(" ")[0]
            entries[flag] = body.strip()
        else:
            assert flag and line.startswith(" " * 10), f"stray help line {line!r}"
            entries[flag] += " " + line.strip()
    return entries


@pytest.mark.parametrize("name", list(cli.COMMANDS))
def test_command_help_describes_every_field_in_one_entry(name, capsys, monkeypatch):
    """Every option of every command has a description of its own (not only a default), short enough to read,
    no LeRobot-derived field (env.features ...) is listed and no default is a long object repr."""
    monkeypatch.setenv("COLUMNS", "120")
    assert cli.main([name, "--help"]) == 0
    text = capsys.readouterr().out
    entries = _help_entries(text)
    assert len(entries) > 3
    for flag, body in entries.items():
        description = body.split(" [default: ")[0].strip()
        assert description and not description.startswith("[default:"), f"{name} {flag}: no description"
        assert len(description) <= 260, f"{name} {flag}: a {len(description)}-character description"
    assert not [f for f in entries if f.rsplit(".", 1)[-1] in ("features", "features_map", "input_features")]
    assert "PolicyFeature(" not in text and "<NormalizationMode" not in text and "lerobot.configs" not in text
    assert max(len(line) for line in text.split("\n")) <= 120


def test_train_help_lists_the_options_of_the_policy_type_asked_for(capsys, monkeypatch):
    """``lerobot-pnp train --policy.type=pnp_pixels --help`` (or a pnp_pixels config file) lists the camera planner's
    options; without a type, the state planner's."""
    monkeypatch.setenv("COLUMNS", "120")
    config = str(Path(__file__).resolve().parents[1] / "configs" / "train_pnp_pixels.json")
    for args in (["--policy.type=pnp_pixels", "--help"], ["--help", f"--config_path={config}"]):
        assert cli.main(["train", *args]) == 0
        entries = _help_entries(capsys.readouterr().out)
        assert "--policy.keypoint_strength" in entries and "--policy.image_downsample" in entries, args
    assert cli.main(["train", "--help"]) == 0
    assert "--policy.keypoint_strength" not in _help_entries(capsys.readouterr().out)


def test_help_keeps_a_default_on_one_line():
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.support.cli_help import command_help

    text = command_help("x", "summary", BaxterPnPEnvConfig)
    assert "[default:\n" not in text and not any(line.strip().endswith("[default:") for line in text.split("\n"))
    assert "--drop_window tuple[float, float]" in text and "[default: (0.0, 0.0)]" in text


def test_help_names_every_preset(capsys):
    from lerobot_pnp.presets import PRESETS

    assert cli.main(["generate", "--help"]) == 0
    line = next(row for row in capsys.readouterr().out.split("\n  --") if row.startswith("env.preset "))
    assert all(name in line for name in PRESETS), line


def test_train_reads_a_lerobot_train_config_file(monkeypatch, tmp_path):
    import lerobot_pnp.train_fast as train_fast

    seen = []
    monkeypatch.setattr(train_fast, "train_fast", seen.append)
    config = Path(__file__).resolve().parents[1] / "configs" / "train_pnp_lstm_full.json"
    out = tmp_path / "out"
    assert cli.main(["train", "--config_path", str(config), f"--output_dir={out}", "--policy.hidden_size=32"]) == 0
    (cfg,) = seen
    stock = json.loads(config.read_text())
    assert cfg.dataset_repo_id == stock["dataset"]["repo_id"] and cfg.dataset_root == stock["dataset"]["root"]
    assert cfg.policy.mode == "recovering" and cfg.policy.max_episode_length == stock["policy"]["max_episode_length"]
    assert cfg.policy.hidden_size == 32 and cfg.batch_size == stock["batch_size"]  # a flag overrides the file
    assert cfg.output_dir == str(out)


def test_train_refuses_another_policy_type_in_a_lerobot_train_config(tmp_path, capsys):
    config = tmp_path / "act.json"
    config.write_text(json.dumps({"dataset": {"repo_id": "local/x"}, "policy": {"type": "act"}}))
    assert cli.main(["train", "--config_path", str(config)]) == 2
    err = capsys.readouterr().err
    assert "the fast path trains ['pnp_lstm', 'pnp_pixels']; the policy type is 'act'" in err and err.count("\n") == 1


def test_train_points_a_lookup_table_to_its_command(capsys):
    assert cli.main(["train", "--policy.type", "pnp_lookup_table"]) == 2
    err = capsys.readouterr().err
    assert "a lookup table is written by 'lerobot-pnp lookup-table'" in err and err.count("\n") == 1


def test_unknown_command_exits_2(capsys):
    assert cli.main(["frobnicate"]) == 2
    err = capsys.readouterr().err
    assert "unknown command 'frobnicate'" in err
    assert "generate" in err  # the usage follows the message


def _bad_value_outcome(argv: list[str], capsys) -> tuple[int, str]:
    """(exit status, everything printed or raised) of ``cli.main(argv)``; an exception counts as status 1."""
    try:
        rc = cli.main(argv)
        text = ""
    except SystemExit as exc:  # argparse/draccus-style exit
        rc, text = (exc.code if isinstance(exc.code, int) else 1), str(exc)
    except Exception as exc:
        rc, chain = 1, []
        while exc is not None:
            chain.append(str(exc))
            exc = exc.__cause__ or exc.__context__
        text = "\n".join(chain)
    captured = capsys.readouterr()
    return rc, text + captured.out + captured.err


@pytest.mark.parametrize(
    ("argv", "field"),
    [
        (["generate", "--num_episodes=-1"], "num_episodes"),
        (["generate", "--env.control_mode=bogus"], "control_mode"),
        (["expert", "--n_episodes=0"], "n_episodes"),
    ],
)
def test_bad_config_value_fails_naming_the_field(argv, field, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # nothing may be written in the repo
    rc, text = _bad_value_outcome([*argv, f"--root={tmp_path / 'ds'}"] if argv[0] == "generate" else argv, capsys)
    assert rc == 2
    assert field in text, text
    assert "Traceback" not in text
    assert not (tmp_path / "ds").exists()


def test_bad_config_value_subprocess_message(tmp_path):
    """The console script, in a process of its own (forked from a warm interpreter, tests/zygote.py), exits 2 with
    one line naming the field, not a traceback."""
    proc = zygote.run([_exe("lerobot-pnp"), "generate", "--num_episodes=-1", f"--root={tmp_path / 'ds'}"], tmp_path, 60)
    assert proc.returncode == 2
    assert "num_episodes must be an integer >= 1" in proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr


def test_an_invalid_mujoco_gl_is_one_line_naming_the_backends(tmp_path):
    """MuJoCo raises a bare RuntimeError from inside ``import mujoco`` for a MUJOCO_GL it does not know; our
    commands refuse it first, in one line that names the backends."""
    proc = _run([_exe("lerobot-pnp"), "expert", "--n_episodes=1"], tmp_path, 60, env={**ENV, "MUJOCO_GL": "bogus"})
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "MUJOCO_GL='bogus' is not a MuJoCo rendering backend: use one of egl" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr


def test_expert_three_episodes(capsys):
    assert cli.main(["expert", "--n_episodes", "3"]) == 0
    out = capsys.readouterr().out
    result = json.loads(out[out.index("{") :])
    assert result["n_episodes"] == 3
    assert result["success_rate"] == 1.0


def test_expert_output_dir_replaces_only_its_own_eval_info(tmp_path, capsys):
    """``expert --output_dir`` writes eval_info.json through the output folder's owner: its own file (recorded, or
    written before the manifest) is replaced, a user's file of that name is refused in one line and kept."""
    from lerobot_pnp.outputs import MANIFEST_FILE

    out = tmp_path / "expert"
    args = ["expert", "--n_episodes", "1", "--progress", "false", "--output_dir", str(out)]
    assert cli.main(args) == 0 and cli.main([*args, "--seed", "3"]) == 0
    assert json.loads((out / "eval_info.json").read_text())["per_task"][0]["metrics"]["seeds"] == [3]
    (out / MANIFEST_FILE).unlink()  # as the command wrote it before the manifest existed
    assert cli.main(args) == 0
    assert json.loads((out / "eval_info.json").read_text())["per_task"][0]["metrics"]["seeds"] == [0]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "eval_info.json").write_text('{"per_task": []}')
    capsys.readouterr()
    assert cli.main([*args[:-1], str(mine)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "eval_info.json" in err, err
    assert (mine / "eval_info.json").read_text() == '{"per_task": []}'


# ---------------------------------------------------------------------------------------------- slow
def test_in_process_eval_keeps_one_progress_bar_and_none_in_a_log(capsys):
    from lerobot.scripts import lerobot_eval

    from lerobot_pnp.support.progress import quiet_rollout_bars

    stock = lerobot_eval.trange
    with quiet_rollout_bars():
        rollout = lerobot_eval.trange(3, desc="Running rollout with at most 3 steps", leave=False)
        batches = lerobot_eval.trange(2, desc="Stepping through eval batches", disable=False)
        assert rollout.disable, "the per-rollout bar must be off"
        assert batches.disable, "stderr is captured (no terminal): tqdm hides the batches bar"
        list(rollout), list(batches)
    assert lerobot_eval.trange is stock
    assert "Running rollout" not in capsys.readouterr().err


@pytest.mark.slow
def test_stock_lerobot_train_help_documents_the_policy_fields(tmp_path):
    """Our field docs are attribute docstrings or field comments, the forms draccus (LeRobot's parser) shows: the
    policy's and the env's task fields (one description each, the same as ``lerobot-pnp --help``); no '%' crash."""
    cmd = [_exe("lerobot-train"), "--policy.type=pnp_lstm", "--env.type=baxter_pnp", "--help"]
    proc = zygote.run(cmd, tmp_path, timeout=120)  # lerobot-train's entry point in a process forked from a warm one
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = " ".join(proc.stdout.split())  # argparse wraps to the terminal
    assert "LSTM hidden units." in out and "Recovering mode: the longest episode" in out
    assert "--env.drop_prob [float] per chance: the object is knocked out of the gripper in transport" in out
    assert "--env.carry_min_time [float] keyframe moves carrying the object" in out
    # LeRobot's derived fields are not offered as flags (cli_help.annotate_stock_help), its undocumented ones are
    derived = ("--env.features", "--policy.input_features", "--policy.output_features")
    assert not [flag for flag in derived if flag in out]
    assert "--env.max_parallel_tasks int lerobot-eval: tasks of a multi-task env evaluated at once" in out


def test_lerobots_own_help_of_our_configs_hides_derived_fields(capsys):
    """draccus (LeRobot's parser) builds LeRobot's --help from the config's fields: ours hide the derived ones and
    describe LeRobot's undocumented ones, and still parse; LeRobot's own classes are left as they are."""
    import dataclasses

    import draccus
    from lerobot.envs.configs import EnvConfig

    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    with pytest.raises(SystemExit):
        draccus.parse(BaxterPnPEnvConfig, args=["--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "--features " not in out and "--features_map" not in out and "--drop_prob [float]" in out
    assert "--disable_env_checker bool skip gymnasium's env checker in gym.make" in out
    assert draccus.parse(BaxterPnPEnvConfig, args=["--drop_prob", "0.5"]).drop_prob == 0.5
    assert "custom_args" not in {f.name: f for f in dataclasses.fields(EnvConfig)}["features"].metadata


def test_train_with_a_malformed_config_file_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"dataset": {"repo_id": ')
    assert cli.main(["train", "--config_path", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "not a readable JSON/YAML config" in err and len(err.strip().splitlines()) == 1, err
