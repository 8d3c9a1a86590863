"""Configs a reader can predict: building a config reads no file and no command line; the recorded task is read
at the edge (``from_source``, a stock script's plugin load, ``lerobot-pnp``'s parser) and handed over as a value,
as a value (``test_stock_suites`` shows ``lerobot-eval`` resolving the task a test builds from the same record)."""

from __future__ import annotations

import builtins
import io
import pathlib
import sys

import pytest

import lerobot_pnp.sim.stock_suites  # noqa: F401  (imported by the env config's checks: loaded before the patches)
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.integration.registration import hand_over_command_line
from lerobot_pnp.policy.configuration_pnp_lookup_table import PnpLookupTableConfig
from lerobot_pnp.policy.configuration_pnp_lstm import PnpLstmConfig
from lerobot_pnp.policy.configuration_pnp_pixels import PnpPixelsConfig
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.recorded_files import write_recorded


class _Untouchable(list):
    """A ``sys.argv`` that fails on any read."""

    def _refuse(self, *args, **kwargs):
        raise AssertionError("sys.argv was read while a config was built")

    __getitem__ = __iter__ = __len__ = __contains__ = __bool__ = _refuse


def _refuse_io(*args, **kwargs):
    raise AssertionError("a file was read while a config was built")


def _forbid_io(monkeypatch) -> None:
    """Every file-reading function and ``sys.argv`` raise until ``monkeypatch`` is undone."""
    monkeypatch.setattr(sys, "argv", _Untouchable())
    for owner, name in ((builtins, "open"), (io, "open")):
        monkeypatch.setattr(owner, name, _refuse_io)
    for name in ("open", "read_text", "read_bytes", "is_file", "exists", "stat"):
        monkeypatch.setattr(pathlib.Path, name, _refuse_io)


def test_no_post_init_reads_a_file_or_the_command_line(tmp_path, monkeypatch):
    write_recorded(BaxterPnPEnvConfig(preset="full", control_mode="dense"), tmp_path)
    record = BaxterPnPEnvConfig.read_source(tmp_path)  # the edge: read before the patches
    monkeypatch.setattr(BaxterPnPEnvConfig, "edge_records", {None: record})  # a stock script's, handed over
    expected = BaxterPnPEnvConfig(recorded=record).to_dict()
    with pytest.MonkeyPatch.context() as patch:
        _forbid_io(patch)
        assert BaxterPnPEnvConfig().to_dict() == expected  # the handed-over record, as a value
        assert BaxterPnPEnvConfig(preset="paper").preset == "paper"
        assert BaxterPnPEnvConfig(recorded=record, nudge_max=0.01).with_changes(drop_prob=0.0).drop_prob == 0.0
        assert PnpLstmConfig().type == "pnp_lstm"
        assert PnpPixelsConfig().type == "pnp_pixels"
        assert PnpLookupTableConfig().type == "pnp_lookup_table"
    assert expected["control_mode"] == "dense" and expected["preset"] == "full"


def test_a_task_source_is_read_at_the_edge_only(tmp_path, monkeypatch):
    write_recorded(BaxterPnPEnvConfig(preset="full"), tmp_path)
    monkeypatch.setattr(BaxterPnPEnvConfig, "edge_records", {})
    assert BaxterPnPEnvConfig.from_source(tmp_path).preset == "full"  # Python callers: the edge is from_source
    assert BaxterPnPEnvConfig.from_dict({"task_source": str(tmp_path)}).preset == "full"
    with pytest.raises(ConfigError, match="env.task_source .* was not read where the config was built"):
        BaxterPnPEnvConfig(task_source=str(tmp_path))  # the config itself reads nothing
    (tmp_path / "meta/baxter_pnp_env.json").write_text("{not json")
    monkeypatch.setattr(sys, "argv", ["lerobot-eval", f"--policy.path={tmp_path}"])
    hand_over_command_line()  # a bad record: the error is kept, raised by the config that uses it
    with pytest.raises(ConfigError, match="cannot read the recorded env config"):
        BaxterPnPEnvConfig()
    assert BaxterPnPEnvConfig(preset="paper").preset == "paper"  # a preset does not use it


def test_lerobot_pnp_commands_read_env_task_source_at_their_parser(tmp_path):
    from lerobot_pnp.cli import config_of

    write_recorded(BaxterPnPEnvConfig(preset="full"), tmp_path / "ds")
    cfg = config_of("expert", [f"--env.task_source={tmp_path / 'ds'}"])
    assert cfg.env.to_dict() == BaxterPnPEnvConfig.from_source(tmp_path / "ds").to_dict()
