"""The catalogue's building blocks: a named evaluation condition (``Suite``) and an axis of the held-out protocol
(``Axis``). Plain data over env-config field names; ``suites`` holds the catalogue."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from lerobot_pnp.errors import ConfigError


@dataclass(frozen=True)
class Suite:
    """A named evaluation condition: env-config ``changes`` per part, with the share of episodes of each."""

    name: str
    description: str
    parts: tuple[dict[str, Any], ...] = ({},)
    group: str = ""  # suites of one sweep share a group (a robustness curve)
    x: float | None = None  # the swept value in that group
    x_label: str = ""
    x_scale: float = 1.0  # x in the unit of x_label (a figure's axis): 100 for cm, 1000 for mm

    def part_episodes(self, n_episodes: int) -> list[int]:
        """Episodes of each part (as equal as possible, summing to ``n_episodes``)."""
        k = len(self.parts)
        return [n_episodes // k + (1 if i < n_episodes % k else 0) for i in range(k)]

    def env_configs(self, base: Any) -> list[Any]:
        """The env config of each part: ``base`` (the training task, a ``BaxterPnPEnvConfig``) with this suite's
        changes. The catalogue imports no env config: the env config checks ``--env.task``'s names against it."""
        out = []
        for changes in self.parts:
            try:  # with_changes lets the episode length follow a changed keyframe budget
                out.append(base.with_changes(**changes))
            except ConfigError as err:
                raise ConfigError(f"suite {self.name!r}: {err}") from None
        return out


@dataclass(frozen=True)
class Axis:
    """One axis of the held-out protocol: suites drawn from the training condition (for a disturbance axis the
    `full` preset's distributions, for a visual axis the visual training ranges) and suites beyond it on this axis
    only (the report prints the two side by side)."""

    name: str
    description: str
    in_distribution: tuple[str, ...]
    held_out: tuple[str, ...]
