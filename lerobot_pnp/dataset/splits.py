"""A dataset's train/test split: one parser, one train-fraction rule.

LeRobot keeps the split in ``meta/info.json`` ``"splits"`` as ``"start:stop"`` strings (``{"train": "0:1120",
"test": "1120:1400"}``). Every reader of a split goes through ``parse_range`` / ``recorded_splits`` here, and
every writer of one through ``split_of``, so "the training episodes" means the same episodes for the
generator, the fast trainer, the study's lookup table and ACT, and DAgger.
"""

from __future__ import annotations

from pathlib import Path

from lerobot_pnp.dataset.layout import read_info
from lerobot_pnp.errors import ConfigError, DatasetError

TRAIN_FRACTION = 0.8  # the generator's default: the first 80 % of the episodes train, the rest are held out
TEST_SPLIT_NAMES = ("test", "val", "validation", "eval")  # what the fast trainer accepts as the held-out split
FALLBACK_TEST_FRACTION = 0.2  # held out by the fast trainer when the dataset records no test split


# ---------------------------------------------------------------------------------------------- ranges
def parse_range(spec: str, n_episodes: int | None = None, error: type[Exception] = ConfigError) -> range:
    """Episode indices of ``"start:stop"``, within ``0:n_episodes`` when that is given.

    ``error`` is the exception raised for a bad value: ConfigError for a range the user asked for,
    DatasetError for one read from a dataset.
    """
    try:
        a, b = (int(x) for x in str(spec).split(":"))
    except ValueError:
        raise error(f"episode range {spec!r} is not of the form 'start:stop'") from None
    if n_episodes is not None and not 0 <= a <= b <= n_episodes:
        raise error(f"episode range {spec!r} is outside the dataset's episodes 0:{n_episodes}")
    return range(a, b)


def range_spec(episodes: range) -> str:
    """``"start:stop"`` of a contiguous range of episodes (the form ``meta/info.json`` and ``--test_episodes`` take)."""
    return f"{episodes.start}:{episodes.stop}"


def recorded_splits(root: str | Path) -> dict[str, range]:
    """Every split recorded in ``meta/info.json`` (``{}`` when it records none); DatasetError on a bad one."""
    splits = read_info(root).get("splits") or {}
    out = {}
    for name, spec in splits.items():
        try:
            out[name] = parse_range(spec, error=DatasetError)
        except DatasetError:
            raise DatasetError(f"meta/info.json split {name!r} = {spec!r} is not 'start:end'") from None
    return out


def recorded_split(root: str | Path, name: str) -> range:
    """The recorded split ``name`` of the dataset at ``root``; DatasetError when the dataset has none."""
    split = recorded_splits(root).get(name)
    if split is None:
        raise DatasetError(f"{root}: no {name!r} split in meta/info.json")
    return split


def load_split(root: str | Path) -> dict[str, list[int]]:
    """Episode indices of each split stored in ``meta/info.json`` ("splits": {"train": "0:1120", ...})."""
    return {name: list(split) for name, split in recorded_splits(root).items()}


# ---------------------------------------------------------------------------------------------- the rule
def split_of(num_episodes: int, train_fraction: float) -> dict[str, str]:
    """First episodes -> "train", the rest -> "test" (a test split is never empty when one was asked for)."""
    n = num_episodes
    n_train = min(n, max(1, round(train_fraction * n)))
    if train_fraction < 1 and n >= 2:
        n_train = min(n_train, n - 1)
    splits = {"train": f"0:{n_train}"}
    if n_train < n:
        splits["test"] = f"{n_train}:{n}"
    return splits


def train_count(num_episodes: int, train_fraction: float = TRAIN_FRACTION) -> int:
    """How many of ``num_episodes`` generated episodes ``split_of`` puts in the training split."""
    return len(parse_range(split_of(num_episodes, train_fraction)["train"]))


def test_split(num_episodes: int, test_fraction: float) -> str:
    """The ``"test"`` range ``split_of`` holds out of ``num_episodes`` for ``train_fraction = 1 - test_fraction``
    (``"n:n"``, empty, when there is nothing to hold out: a single episode)."""
    n = num_episodes
    return split_of(n, 1 - test_fraction).get("test", f"{n}:{n}")


def train_test(
    splits: dict[str, str] | None, n_episodes: int, test_override: str | None = None
) -> tuple[list[int], list[int], str]:
    """(train episodes, test episodes, source) of the fast trainer.

    The test episodes are ``test_override``, else the first recorded split named in ``TEST_SPLIT_NAMES``,
    else the last ``FALLBACK_TEST_FRACTION`` of the episodes (``split_of``'s rule). The train episodes are
    the recorded ``"train"`` split when the dataset records both, else every other episode; a test episode
    never trains. ConfigError on a bad range or when no episode is left to train on.
    """
    splits = dict(splits or {})
    if test_override is not None:
        test = list(parse_range(test_override, n_episodes))
        source = f"override test={test_override}"
    else:
        name = next((n for n in TEST_SPLIT_NAMES if n in splits), None)
        if name is not None:
            test = list(parse_range(splits[name], n_episodes))
            source = f"meta/info.json splits {splits}"
        else:
            fallback = split_of(n_episodes, 1 - FALLBACK_TEST_FRACTION).get("test")
            test = list(parse_range(fallback)) if fallback else []
            source = f"fallback: last {len(test)} of {n_episodes} episodes held out (no test split in meta/info.json)"
    test_set = set(test)
    if test_override is None and "train" in splits and any(n in splits for n in TEST_SPLIT_NAMES):
        train = [e for e in parse_range(splits["train"], n_episodes) if e not in test_set]
    else:
        train = [e for e in range(n_episodes) if e not in test_set]
    if not train:
        raise ConfigError(f"the split leaves no training episodes ({source})")
    return train, test, source
