"""The runs of ``lerobot-pnp compare``: each argument read into a ``Run`` and every run checked against the others.

An argument is ``PATH`` or ``NAME=PATH[,PATH...]`` (the training seeds of one method, pooled). Paths may hold
``=`` and ``,`` (``sweep/lr=0.1``), so an argument is read by this rule:

1. an argument that is an existing file or folder is one ``PATH``, named after its folder;
2. otherwise it is ``NAME=PATHS``, split at its first ``=`` -- unless the text before that ``=`` is itself an
   existing path, when the argument is one ``PATH`` that does not exist (and is refused as such);
3. ``PATHS`` splits at each ``,``, except where pieces joined with their commas name an existing path (the
   longest such join wins).

Runs pair episode by episode (``compare``): a run's paths hold the same tasks and episode counts, and runs hold
the same counts on every suite they share. Where two files record their episodes' seeds (``lerobot-pnp
expert``'s ``metrics.seeds``), the seeds must be the same; a stock ``lerobot-eval`` file records none, and its
episodes pair by index (episode ``i`` is seed ``--seed + i``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.eval_info import EvalInfo, read_eval_info


@dataclass(frozen=True)
class Run:
    name: str
    paths: tuple[str, ...]
    suites: tuple[dict[str, dict[int, list[bool]]], ...]  # per path: suite -> task id -> successes
    seeds: tuple[dict[str, dict[int, list[int]]], ...] = ()  # per path: suite -> task id -> recorded seeds
    spec: str = ""  # the argument as given

    def who(self, k: int) -> str:
        """``run 'name'``, with the path when the run pools several."""
        return f"run {self.name!r}" + (f" ({self.paths[k]!r})" if len(self.paths) > 1 else "")

    @property
    def records_seeds(self) -> bool:
        """Every task of every path records its episodes' seeds."""
        return all(set(s) == set(seeds) and all(set(s[g]) == set(seeds[g]) for g in s)
                   for s, seeds in zip(self.suites, self.seeds, strict=True))  # fmt: skip


def _exists(path: str) -> bool:
    try:
        return Path(path).exists()
    except (OSError, ValueError):  # a name the system cannot hold (an embedded NUL, too long)
        return False


def _default_name(path: str) -> str:
    p = Path(path)
    name = p.parent.name if p.is_file() else p.name
    return name or path


def _split_paths(text: str) -> tuple[str, ...]:
    """``PATHS`` split at commas, keeping together the pieces whose join is an existing path (longest first)."""
    pieces, out, i = text.split(","), [], 0
    while i < len(pieces):
        j = next((j for j in range(len(pieces), i + 1, -1) if _exists(",".join(pieces[i:j]))), i + 1)
        out.append(",".join(pieces[i:j]))
        i = j
    return tuple(p for p in out if p)


def split_run(spec: str) -> tuple[str, tuple[str, ...]]:
    """(name, paths) of one argument, by the module's rule."""
    if _exists(spec):
        return _default_name(spec), (spec,)
    name, eq, rest = spec.partition("=")
    if not eq or _exists(name):
        return _default_name(spec), (spec,)
    paths = _split_paths(rest)
    if not name or not paths:
        raise ConfigError(f"compare: run argument {spec!r} is not PATH or NAME=PATH[,PATH...]")
    return name, paths


def _only(info: EvalInfo, keep: list[str] | None) -> tuple[dict, dict]:
    """The suites named in ``keep`` (all when None); a file that lacks one is refused, naming what it holds."""
    if keep is None:
        return info.suites, info.seeds
    missing = [s for s in keep if s not in info.suites]
    if missing:
        raise ConfigError(f"compare: {str(info.file)!r} holds no suite {missing[0]!r}; it holds {sorted(info.suites)}")
    return {s: info.suites[s] for s in keep}, {s: info.seeds[s] for s in keep if s in info.seeds}


def _read(path: str, spec: str) -> EvalInfo:
    """``read_eval_info`` whose one-line refusals also name the whole argument the path came from."""
    try:
        return read_eval_info(path)
    except ConfigError as err:
        if spec == path and "=" in spec:
            hint = " (its text before '=' is an existing path, so the argument is one PATH, not NAME=PATH)"
        elif spec != path:
            name, _, paths = spec.partition("=")
            hint = f" (run argument {spec!r}, read as NAME {name!r} = PATHS {paths!r}; a PATH may hold '=' and ','"
            hint += " where the whole argument, or the PATH, is an existing path)"
        else:
            hint = ""
        raise ConfigError(f"{err}{hint}") from None


def read_run(spec: str, keep: list[str] | None = None) -> Run:
    """One argument read: its paths' suites (those in ``keep``) and seeds, the paths holding the same counts."""
    name, paths = split_run(spec)
    read = [_only(_read(p, spec), keep) for p in paths]
    suites, seeds = tuple(r[0] for r in read), tuple(r[1] for r in read)
    for p, s in zip(paths[1:], suites[1:], strict=True):
        if counts(s) != counts(suites[0]):
            raise ConfigError(
                f"compare: run {name!r}: {p!r} does not hold the suites and episode counts of {paths[0]!r}"
            )
    return Run(name, paths, suites, seeds, spec)


def counts(suites: dict[str, dict[int, list[bool]]]) -> dict[str, dict[int, int]]:
    return {s: {t: len(v) for t, v in tasks.items()} for s, tasks in suites.items()}


def pairs_of(a: Run, b: Run) -> list[tuple[int, int]]:
    """Which training seed of ``a`` pairs with which of ``b``: one to one, or each against a run of one."""
    na, nb = len(a.paths), len(b.paths)
    if na == nb:
        return [(k, k) for k in range(na)]
    if na == 1 or nb == 1:
        return [(k if na > 1 else 0, k if nb > 1 else 0) for k in range(max(na, nb))]
    raise ConfigError(
        f"compare: runs {a.name!r} ({na} paths) and {b.name!r} ({nb}) pair neither one to one nor against a run of one"
    )


def _check_pair(a: Run, b: Run) -> None:
    ca, cb = counts(a.suites[0]), counts(b.suites[0])
    shared = set(ca) & set(cb)
    if not shared:
        raise ConfigError(f"compare: runs {a.name!r} and {b.name!r} share no suite")
    bad = sorted(s for s in shared if ca[s] != cb[s])
    if bad:
        raise ConfigError(
            f"compare: runs {a.name!r} and {b.name!r} do not pair on {bad[:3]}"
            f"{f' and {len(bad) - 3} more suites' if len(bad) > 3 else ''}: episodes per task {ca[bad[0]]} "
            f"vs {cb[bad[0]]} (run both with the same --eval.n_episodes and --seed)"
        )
    pairs_of(a, b)


def check_seeds(runs: list[Run]) -> None:
    """Every file that records the seeds of a suite's task records the same ones as the first that does (the
    counts are already the same): two runs evaluated from different ``--seed`` do not pair."""
    first: dict[tuple[str, int], tuple[str, list[int]]] = {}
    for run in runs:
        for k, per in enumerate(run.seeds):
            for suite, tasks in per.items():
                for task, seeds in tasks.items():
                    who, ref = first.setdefault((suite, task), (run.who(k), seeds))
                    if seeds != ref:
                        i = next(i for i, (x, y) in enumerate(zip(ref, seeds, strict=True)) if x != y)
                        raise ConfigError(
                            f"compare: {who} and {run.who(k)} were evaluated on other seeds (suite {suite!r} task "
                            f"{task}, episode {i}: seed {ref[i]} vs {seeds[i]}); compare runs of the same --seed"
                        )


def check_control_seeds(run: Run, suite: str, control: str) -> None:
    """A suite and the control pair episode by episode within one file: where both record seeds, the same."""
    for k, per in enumerate(run.seeds):
        a, b = per.get(suite, {}), per.get(control, {})
        for task in sorted(a.keys() & b.keys()):
            m = min(len(a[task]), len(b[task]))
            if a[task][:m] != b[task][:m]:
                raise ConfigError(
                    f"compare: {run.who(k)} records other seeds on suite {suite!r} than on the control {control!r} "
                    f"(task {task}); each suite must start at the same --seed"
                )


def parse_runs(specs: list[str], suites: str | None = None) -> list[Run]:
    """Each argument read and checked: a run's paths hold the same tasks and counts (its training seeds pool on
    the same episodes); runs share at least one suite, with the same counts on every suite they share, and the
    same recorded seeds. ``suites`` (comma-separated) keeps only those suites of every path, so that runs
    evaluated on different sets of suites pool and pair on the ones they share."""
    if not specs:
        raise ConfigError("compare: give at least one run (PATH or NAME=PATH[,PATH...])")
    keep = None if suites is None else [s.strip() for s in suites.split(",") if s.strip()]
    if keep is not None and not keep:
        raise ConfigError("compare: suites is empty; give suite names, comma-separated")
    runs = [read_run(spec, keep) for spec in specs]
    names = [r.name for r in runs]
    if len(set(names)) != len(runs):
        raise ConfigError(f"compare: run names repeat: {names}; name them NAME=PATH")
    for i, a in enumerate(runs):
        for b in runs[i + 1 :]:
            _check_pair(a, b)
    check_seeds(runs)
    return runs
