"""Where the env config meets the disk: the recorded tasks of datasets and checkpoints, read at the edge.

Building a ``BaxterPnPEnvConfig`` reads no file and no command line. A caller with a dataset folder or a checkpoint
reads its recorded task here (``from_source``); a command line's sources are read before it is parsed
(``read_edge_records``, by ``lerobot-pnp`` and by the stock scripts' registration), and the configs the parse builds
take theirs from ``edge_records`` while it runs (``reading_edge_records``). A record that fails its check is kept as
its error and raised by the config that uses it, so a bad source named for one config does not fail another.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import ClassVar

from lerobot_pnp.errors import ConfigError, shown
from lerobot_pnp.sim.recorded_files import check_record, find_recorded


class EdgeRecords:
    """The env config's records read at the edge (a base of ``BaxterPnPEnvConfig``, no fields of its own)."""

    # The records read at the edge, by source (None: the default source of a stock script's command line); a
    # record is a dict ({}: the source records none) or the ConfigError reading it raised (raised on use)
    edge_records: ClassVar[dict[str | None, dict | ConfigError]] = {}
    task_source: str | None

    def _edge_record(self) -> dict:
        """The record of ``task_source`` (else of the command line's default source) read at the edge."""
        record = self.edge_records.get(self.task_source, {} if self.task_source is None else None)
        if record is None:
            raise ConfigError(
                f"env.task_source {shown(self.task_source)} was not read where the config was built: build it with "
                "BaxterPnPEnvConfig.from_source(source, **fields), or name it on the command line (--env.task_source)"
            )
        if isinstance(record, ConfigError):
            raise record
        return record

    @classmethod
    def read_source(cls, source: str | Path) -> dict:
        """The task recorded with a dataset folder or checkpoint, checked (``recorded_files.check_record``); {}
        when it records none."""
        found = find_recorded(source)
        return check_record(*found, cls) if found is not None else {}

    @classmethod
    def from_source(cls, source: str | Path, **fields_):
        """A config starting from the task ``source`` (a dataset folder or checkpoint) records, read here."""
        recorded = cls.read_source(source) if fields_.get("preset") is None else {}
        return cls(task_source=str(source), recorded=recorded, **fields_)

    @classmethod
    def read_edge_records(cls, sources: dict[str | None, str | None]) -> dict[str | None, dict | ConfigError]:
        """The records of ``sources`` (key: the ``task_source`` they stand for, None the default source), each a
        record, {} or the ConfigError reading it raised (a bad record fails the config that uses it)."""
        out: dict[str | None, dict | ConfigError] = {}
        for key, source in sources.items():
            try:
                out[key] = cls.read_source(source) if source else {}
            except ConfigError as err:
                out[key] = err
        return out

    @classmethod
    @contextmanager
    def reading_edge_records(cls, records: dict[str | None, dict | ConfigError]) -> Iterator[None]:
        """``edge_records`` while a command line is parsed into configs, then the previous ones again."""
        before, cls.edge_records = cls.edge_records, records
        try:
            yield
        finally:
            cls.edge_records = before
