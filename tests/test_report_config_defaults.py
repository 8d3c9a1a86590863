"""One nested flag of `lerobot-pnp report` / `demo` changes that one field: every other field of the nested
config keeps its default, and where the default comes from the preset (``--episodes_rule.*``: the preset's
rule), the preset's value. Parsed through the command line, the study itself replaced by a stand-in."""

from __future__ import annotations

from dataclasses import fields, replace

import pytest

from lerobot_pnp import cli, demo
from lerobot_pnp.report import run
from lerobot_pnp.report.config import PRESETS, EpisodeRule, StudyConfig
from lerobot_pnp.report.slurm import StudySlurmOptions

# a valid value other than the default, for each --slurm.* field
SLURM_VALUES = {
    "partition": "gpu",
    "cpus_per_task": 4,
    "mem_per_cpu_gb": 3,
    "time": "1-00:00:00",
    "qos": "high",
    "job_name": "mine",
    "suites_per_job": 2,
    "dataset_cpus": 8,
}
RULE_VALUES = {
    "half_width": 0.2,
    "block": 100,
    "fixed_methods": ["expert"],
    "claim_methods": ["recovering"],
    "claim_half_width": 0.03,
    "claim_max_factor": 3,
}


@pytest.fixture
def parsed(monkeypatch):
    """``parsed(command, *flags)``: the config the command line gives the study (nothing runs)."""
    seen = []
    monkeypatch.setattr(run, "run_study", seen.append)
    monkeypatch.setattr(demo, "run_demo", seen.append)

    def parse(command: str, *flags: str):
        assert cli.main([command, *flags]) == 0
        return seen.pop()

    return parse


def _flag(value) -> str:
    return "[" + ",".join(value) + "]" if isinstance(value, list) else str(value)


def test_every_slurm_field_is_covered():
    assert set(SLURM_VALUES) == {f.name for f in fields(StudySlurmOptions)}
    assert set(RULE_VALUES) == {f.name for f in fields(EpisodeRule)}
    assert all(getattr(StudySlurmOptions(), k) != v for k, v in SLURM_VALUES.items())


@pytest.mark.parametrize("command", ["report", "demo"])
@pytest.mark.parametrize("name", sorted(SLURM_VALUES))
def test_one_slurm_flag_keeps_every_other_default(parsed, command, name):
    cfg = parsed(command, f"--slurm.{name}", _flag(SLURM_VALUES[name]))
    assert cfg.slurm == replace(StudySlurmOptions(), **{name: SLURM_VALUES[name]})


@pytest.mark.parametrize("command", ["report", "demo"])
@pytest.mark.parametrize("preset", ["demo", "full", "heldout", "recovery_demo"])
@pytest.mark.parametrize("name", sorted(RULE_VALUES))
def test_one_episodes_rule_flag_keeps_the_rest_of_the_presets_rule(parsed, command, preset, name):
    value = RULE_VALUES[name]
    if (
        name == "claim_methods"
        and "recovering" in (PRESETS[preset].get("episodes_rule") or EpisodeRule()).fixed_methods
    ):
        value = ["act"]  # a method named in both lists is refused
    cfg = parsed(command, "--preset", preset, f"--episodes_rule.{name}", _flag(value))
    rule = PRESETS[preset].get("episodes_rule") or EpisodeRule()  # the preset's rule, else the rule's defaults
    value = tuple(value) if isinstance(value, list) else value
    assert cfg.episodes_rule == replace(rule, **{name: value})


def test_a_partial_rule_in_a_config_keeps_the_rest_of_the_presets_rule():
    full = PRESETS["full"]["episodes_rule"]
    assert StudyConfig(preset="full", episodes_rule={"half_width": 0.2}).episodes_rule == replace(full, half_width=0.2)
    assert StudyConfig(preset="full").episodes_rule == full
    whole = EpisodeRule(half_width=0.3)  # a whole rule, as code passes one, is taken as it is
    assert StudyConfig(preset="full", episodes_rule=whole).episodes_rule == whole
    assert StudyConfig(preset="full", episodes_rule={"block": 100}, fixed_episodes=True).episodes_rule is None
