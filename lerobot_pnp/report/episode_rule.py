"""The episode rule of a study's evaluations (``StudyConfig.episodes_rule``): ``EpisodeRule``, a claim method's
``ExtendedRule``, and ``RuleChanges``, the fields a command line or config file changes in a preset's rule.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.stats import wilson_interval


@dataclass(frozen=True)
class EpisodeRule:
    """Episode counts chosen from the interval width a cell needs (``StudyConfig.episodes_rule``).

    An evaluation of a method not in ``fixed_methods`` runs its suite's seeds in blocks of ``block`` episodes
    (a multiple of the eval batch size, so each block is exactly batches a fixed-n run makes: its first blocks
    are that run's first episodes, episode by episode) and stops after the first block where the 95 % Wilson
    interval of what it has so far is at most ``half_width`` either side, or at the suite's n. Each evaluation
    decides alone (no coordination between stages, so the job pool runs them side by side).

    A method of ``claim_methods`` is the one whose cells are read against the claims' bars (90 / 95 / 98 %):
    its evaluations run at least the suite's n and go on in blocks while the interval is wider than
    ``claim_half_width`` either side, up to ``claim_max_factor`` times n (``ExtendedRule``). A cell near a bar
    is where an interval at n cannot decide it, and only there are more episodes spent."""

    half_width: float = 0.1  # target 95 % Wilson half-width (a fraction: 0.1 = +-10 pts)
    block: int = 50  # episodes between two looks at the interval; a multiple of StudyConfig.eval_batch_size
    # methods whose evaluations always run the suite's whole n: the claims' methods, and the lookup table, every
    # paired comparison's baseline (a comparison pairs on the seeds both ran: at the baseline's n, the method's)
    fixed_methods: tuple[str, ...] = ("expert", "lookup_table", "recovering")
    # methods whose evaluations run at least the suite's n and more where their interval is still wide
    claim_methods: tuple[str, ...] = ()
    claim_half_width: float = 0.045  # their target 95 % Wilson half-width per evaluation (a fraction)
    claim_max_factor: int = 2  # their most episodes: this times the suite's n

    def check(self, eval_batch_size: int) -> None:
        """A clear ConfigError naming the bad value; methods are checked by ``StudyConfig``."""
        for name in ("half_width", "claim_half_width"):
            if not 0 < getattr(self, name) < 0.5:
                raise ConfigError(f"episodes_rule.{name} must be in (0, 0.5) (a fraction), got {getattr(self, name)!r}")
        if self.block < 1 or self.block % eval_batch_size:
            raise ConfigError(
                f"episodes_rule.block must be a positive multiple of eval_batch_size ({eval_batch_size}), "
                f"got {self.block!r}"
            )
        if not isinstance(self.claim_max_factor, int) or self.claim_max_factor < 1:
            raise ConfigError(f"episodes_rule.claim_max_factor must be an integer >= 1, got {self.claim_max_factor!r}")
        if both := sorted(set(self.claim_methods) & set(self.fixed_methods)):
            raise ConfigError(f"episodes_rule: {both} both in fixed_methods and claim_methods; name each in one")

    def key(self) -> dict:
        """What an adaptive evaluation's stage key records of the rule (``fixed_methods`` decides only whether a
        method's evaluation is adaptive, not what it produces)."""
        return {"half_width": self.half_width, "block": self.block}

    def for_method(self, name: str):
        """The rule ``name``'s evaluations run under: None (the suite's whole n), this rule, or its
        ``ExtendedRule`` for a claim method."""
        if name in self.claim_methods:
            return ExtendedRule(
                half_width=self.claim_half_width, block=self.block, fixed_methods=(), max_factor=self.claim_max_factor
            )
        return None if name in self.fixed_methods else self

    def stops(self, n_episodes: int, batch_size: int) -> list[int]:
        """Where an evaluation of at most ``n_episodes`` may stop: after each block, and at n. A block end that
        leaves fewer than a batch of episodes to n is skipped: that last short run would be a smaller batch than
        the fixed-n run's last one (the episodes of a learned policy can depend on the batch)."""
        return [k for k in range(self.block, n_episodes, self.block) if n_episodes - k >= batch_size] + [n_episodes]

    def stop_at(self, outcomes: list[bool], n_episodes: int, batch_size: int) -> int | None:
        """Episodes the rule keeps of ``outcomes`` (the first seeds' successes, in seed order): the first stop
        whose prefix is decided (half-width <= ``half_width``), the last stop when none is; None if
        ``outcomes`` ends first."""
        stops = self.stops(n_episodes, batch_size)
        for stop in stops:
            if stop > len(outcomes):
                return None
            if stop == stops[-1] or self.decided(sum(map(bool, outcomes[:stop])), stop):
                return stop
        return None  # pragma: no cover - the last stop returns

    def decided(self, successes: int, n: int) -> bool:
        lo, hi = wilson_interval(successes, n)
        return (hi - lo) / 2 <= self.half_width


@dataclass(frozen=True)
class ExtendedRule(EpisodeRule):
    """A claim method's rule (``EpisodeRule.claim_methods``): the suite's n first, exactly as a fixed-n run
    makes them, then blocks until the interval is at most ``half_width`` either side, or at ``max_factor`` x n."""

    max_factor: int = 2

    def key(self) -> dict:
        return {"half_width": self.half_width, "block": self.block, "from_n": True, "max_factor": self.max_factor}

    def stops(self, n_episodes: int, batch_size: int) -> list[int]:
        """n, then every block after it, and ``max_factor`` x n: each extension is whole blocks of seeds after
        the fixed run's last one, so its first n episodes are that run's."""
        most = self.max_factor * n_episodes
        return [*range(n_episodes, most, self.block), most]


@dataclass
class RuleChanges:
    """``--episodes_rule.*`` (or an ``episodes_rule`` mapping in a config file): each field given changes the
    preset's rule (``EpisodeRule``'s own defaults where the preset has none) and each field left out keeps its
    value there, so one flag changes one field. What each field means: ``EpisodeRule``."""

    half_width: float | None = None  # target 95 % Wilson half-width (a fraction); None = the preset's (else 0.1)
    block: int | None = None  # episodes between two looks at the interval; None = the preset's (else 50)
    fixed_methods: list[str] | None = None  # methods run at the suite's whole n; None = the preset's
    claim_methods: list[str] | None = None  # methods run at least n, more while wide; None = the preset's (else none)
    claim_half_width: float | None = None  # their target half-width; None = the preset's (else 0.045)
    claim_max_factor: int | None = None  # their most episodes, times n; None = the preset's (else 2)


def resolve_rule(given, preset_rule: EpisodeRule | None) -> EpisodeRule | None:
    """The rule a study runs under: ``given`` (None: the preset's ``preset_rule``; a whole ``EpisodeRule``: that
    one; ``RuleChanges`` or a mapping: the fields it sets, on top of the preset's rule or, where the preset
    has none, of ``EpisodeRule()``), its method lists as tuples (the stage key's form)."""
    if given is None or isinstance(given, EpisodeRule):
        rule = given if given is not None else preset_rule
    else:
        changes = given if isinstance(given, dict) else {f.name: getattr(given, f.name) for f in fields(given)}
        valid = sorted(f.name for f in fields(EpisodeRule))
        if unknown := sorted(set(changes) - set(valid)):
            raise ConfigError(f"episodes_rule: unknown field(s) {unknown}; valid: {valid}")
        rule = replace(preset_rule or EpisodeRule(), **{k: v for k, v in changes.items() if v is not None})
    if rule is None:
        return None
    return replace(rule, fixed_methods=tuple(rule.fixed_methods), claim_methods=tuple(rule.claim_methods))
