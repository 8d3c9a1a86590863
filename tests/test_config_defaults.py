"""A command's defaults survive the flags given: one nested flag (``--policy.hidden_size 8``) changes that field
and keeps every other default of the nested config, its default factory's included (dagger's recovering recipe),
for every command; ``~`` in a path flag is the user's home for every command."""

from __future__ import annotations

import dataclasses
import enum
import json
from pathlib import Path

import pytest

from lerobot_pnp import cli
from lerobot_pnp.integration.registration import register_all

register_all()


def _nested_fields(config_cls) -> list[tuple[str, object]]:
    """(name, default value) of each nested dataclass field with a default factory."""
    out = []
    for field in dataclasses.fields(config_cls):
        if field.init and field.default_factory is not dataclasses.MISSING:
            value = field.default_factory()
            if dataclasses.is_dataclass(value):
                out.append((field.name, value))
    return out


def _scalar_flag(value) -> tuple[str, str] | None:
    """A field of the dataclass ``value`` holding a plain scalar, and that value as typed on the command line."""
    for field in dataclasses.fields(value):
        current = getattr(value, field.name)
        if not field.init or isinstance(current, enum.Enum):
            continue
        if isinstance(current, bool):
            return field.name, str(current).lower()
        if isinstance(current, int | float | str) and str(current) and " " not in str(current):
            return field.name, str(current)
    return None


NESTED = [
    (name, field, value)
    for name, (ref, _, _) in cli.COMMANDS.items()
    for field, value in _nested_fields(cli._load(ref))
]


def test_every_nested_default_factory_is_covered():
    assert ("dagger", "policy") in {(name, field) for name, field, _ in NESTED}
    assert len({name for name, _, _ in NESTED}) >= 5  # generate, train, viz, expert, dagger, demo, report


@pytest.mark.parametrize(("name", "field", "value"), NESTED, ids=[f"{n}.{f}" for n, f, _ in NESTED])
def test_one_nested_flag_keeps_every_other_default(name, field, value, tmp_path, monkeypatch):
    """The flag re-gives a field its default value: the config must equal the one built without flags, and the
    nested config the default factory's value (draccus alone builds the nested type afresh, dropping the rest)."""
    monkeypatch.chdir(tmp_path)  # a config that looks at its output folder looks here
    flag = _scalar_flag(value)
    if flag is None:  # nothing but a None default (viz's policy path): no other field to lose
        assert len([f for f in dataclasses.fields(value) if f.init]) == 1, f"{name} --{field}: no scalar field"
        return
    plain = cli.config_of(name, [])
    flagged = cli.config_of(name, [f"--{field}.{flag[0]}", flag[1]])
    assert getattr(plain, field) == value
    assert getattr(flagged, field) == value, f"{name} --{field}.{flag[0]} {flag[1]} reset the other defaults"
    assert flagged == plain


def test_a_dagger_policy_flag_keeps_the_recovering_recipe():
    from lerobot_pnp.policy.recipes import RECOVERING_RECIPE

    cfg = cli.config_of("dagger", ["--preset", "paper", "--policy.hidden_size", "8"])
    assert cfg.preset == "paper" and cfg.policy.hidden_size == 8
    assert {k: getattr(cfg.policy, k) for k in RECOVERING_RECIPE} == {**RECOVERING_RECIPE, "hidden_size": 8}


def test_a_config_file_with_part_of_the_policy_keeps_the_rest_of_the_recipe(tmp_path):
    from lerobot_pnp.policy.recipes import RECOVERING_RECIPE

    config = tmp_path / "dagger.json"
    config.write_text(json.dumps({"num_episodes": 10, "policy": {"num_layers": 1}}))
    cfg = cli.config_of("dagger", ["--config_path", str(config), "--policy.hidden_size=16"])
    expected = {**RECOVERING_RECIPE, "num_layers": 1, "hidden_size": 16}
    assert cfg.num_episodes == 10 and {k: getattr(cfg.policy, k) for k in RECOVERING_RECIPE} == expected


def _path_flag(name: str) -> str | None:
    fields = {f.name for f in dataclasses.fields(cli._load(cli.COMMANDS[name][0]))}
    return next((f for f in ("output_dir", "root", "dataset_root", "output") if f in fields), None)


@pytest.mark.parametrize("name", [n for n in cli.COMMANDS if _path_flag(n)])
def test_a_path_flag_starting_with_a_tilde_is_the_home_folder(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    flag = _path_flag(name)
    for args in ([f"--{flag}=~/x"], [f"--{flag}", "~/x"]):
        cfg = cli.config_of(name, args)
        assert getattr(cfg, flag) == str(tmp_path / "home" / "x"), (name, args)
    assert not (tmp_path / "~").exists()


def test_train_writes_a_tilde_output_dir_into_the_home_folder(tmp_path, monkeypatch, capsys):
    """``lerobot-pnp train '--output_dir=~/run'`` trains into $HOME/run, not into a folder named ``~``."""
    from keyframe_synth import REPO_ID, make_keyframe_dataset

    root = tmp_path / "keyframes"
    make_keyframe_dataset(root, n_episodes=6, splits={"train": "0:5", "test": "5:6"})
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    args = ["train", "--dataset_repo_id", REPO_ID, "--dataset_root", str(root), "--output_dir=~/run", "--epochs=1",
            "--batch_size=4", "--policy.hidden_size=8", "--policy.device=cpu", "--progress=false"]  # fmt: skip
    assert cli.main(args) == 0, capsys.readouterr().err
    assert (tmp_path / "home" / "run" / "train_fast_config.json").is_file()
    assert not Path("~").exists()
