"""The one split module (``lerobot_pnp.dataset.splits``) keeps every contract of the parsers it replaced.

The ``_old_*`` functions are the replaced code, verbatim but for names: the study's lookup table, its ACT
baseline and the fast trainer must see the same episode indices as before the move.
"""

import json
import random

import numpy as np
import pytest
import torch

from lerobot_pnp.dataset import load_split
from lerobot_pnp.dataset.layout import info_path, is_dataset
from lerobot_pnp.dataset.splits import (
    parse_range,
    range_spec,
    recorded_split,
    recorded_splits,
    split_of,
    train_count,
    train_test,
)
from lerobot_pnp.errors import ConfigError, DatasetError
from lerobot_pnp.support.determinism import seed_everything


def _old_parse_range(spec, n):  # train_fast/data.py
    a, b = (int(x) for x in str(spec).split(":"))
    if not 0 <= a <= b <= n:
        raise ConfigError(f"episode range {spec!r} is outside the dataset's episodes 0:{n}")
    return list(range(a, b))


def _old_split_episodes(splits, n, test_override=None):  # train_fast/data.py, without the source text
    names = ("test", "val", "validation", "eval")
    splits = dict(splits or {})
    if test_override is not None:
        test = _old_parse_range(test_override, n)
    else:
        name = next((k for k in names if k in splits), None)
        if name is not None:
            test = _old_parse_range(splits[name], n)
        else:
            n_test = max(1, round(0.2 * n)) if n > 1 else 0
            test = list(range(n - n_test, n))
    test_set = set(test)
    if test_override is None and "train" in splits and any(k in splits for k in names):
        train = [e for e in _old_parse_range(splits["train"], n) if e not in test_set]
    else:
        train = [e for e in range(n) if e not in test_set]
    return train, test


@pytest.mark.parametrize(
    "splits, n, override",
    [
        ({"train": "0:240", "test": "240:300"}, 300, None),  # the quick preset's dataset
        ({"train": "0:1120", "test": "1120:1400"}, 1400, None),  # the paper's
        ({"train": "0:10"}, 10, None),  # no test split: the fallback
        ({}, 10, "0:2"),
        ({"train": "0:8", "val": "8:10"}, 10, None),
        ({"train": "0:9", "test": "5:10"}, 10, None),  # overlapping: a test episode never trains
        (None, 7, None),
    ],
)
def test_train_test_matches_the_old_fast_trainer_split(splits, n, override):
    train, test, source = train_test(splits, n, override)
    assert (train, test) == _old_split_episodes(splits, n, override)
    assert ("fallback" in source) == (override is None and not any(k in (splits or {}) for k in ("test", "val")))


def test_the_fallback_is_split_of_for_every_size():
    """The fast trainer's "last 20 % held out" equals the generator's rule at every dataset size."""
    for n in range(1, 5001):
        n_test = max(1, round(0.2 * n)) if n > 1 else 0  # the replaced fallback
        assert split_of(n, 1 - 0.2).get("test", f"{n}:{n}") == f"{n - n_test}:{n}", n
    with pytest.raises(ConfigError, match="leaves no training episodes"):
        train_test({}, 1, test_override="0:1")


def test_parse_range_errors_name_the_value():
    assert parse_range("3:7", 10) == range(3, 7) and range_spec(range(3, 7)) == "3:7"
    with pytest.raises(ConfigError, match="outside the dataset's episodes 0:10"):
        train_test({"test": "0:20"}, 10)
    with pytest.raises(ConfigError, match=r"'a:b' is not of the form 'start:stop'"):
        parse_range("a:b", 10)
    with pytest.raises(DatasetError, match="not of the form"):
        parse_range("1:2:3", error=DatasetError)


def _dataset(tmp_path, splits):
    info_path(tmp_path).parent.mkdir(parents=True)
    info_path(tmp_path).write_text(json.dumps({"total_episodes": 10, **({"splits": splits} if splits else {})}))
    return tmp_path


def test_recorded_splits_keep_each_readers_contract(tmp_path):
    assert not is_dataset(tmp_path)
    root = _dataset(tmp_path / "d", {"train": "0:8", "test": "8:10"})
    assert is_dataset(root)
    assert recorded_splits(root) == {"train": range(8), "test": range(8, 10)}
    assert load_split(root) == {"train": list(range(8)), "test": [8, 9]}  # dataset.load_split's lists
    # the study's lookup table and ACT baseline took np.arange(a, b) of the recorded range
    assert np.array_equal(np.arange(recorded_split(root, "test").start, 10), np.arange(8, 10))
    bare = _dataset(tmp_path / "bare", None)
    assert recorded_splits(bare) == {} and load_split(bare) == {}
    with pytest.raises(DatasetError, match="no 'test' split in meta/info.json"):
        recorded_split(bare, "test")
    bad = _dataset(tmp_path / "bad", {"train": "0-8"})
    with pytest.raises(DatasetError, match="split 'train' = '0-8' is not 'start:end'"):
        recorded_splits(bad)


def test_train_count_is_the_generators_rule():
    for n in (10, 300, 1400):
        assert train_count(n) == int(n * 0.8) == len(range(*map(int, split_of(n, 0.8)["train"].split(":"))))
    assert train_count(12) == 10  # round, as the generator writes it (int(12 * 0.8) said 9)


def _draws():
    return random.random(), float(np.random.rand()), float(torch.rand(()))


def test_seed_everything_is_lerobots_set_seed_below_2_32():
    from lerobot.utils.random_utils import set_seed

    set_seed(1000)
    expected = _draws()
    seed_everything(1000)
    assert _draws() == expected
    seed_everything(2**40 + 1)  # numpy takes the seed modulo 2**32; the configs allow up to 2**63
    big = _draws()
    random.seed(2**40 + 1), np.random.seed(1), torch.manual_seed(2**40 + 1)
    assert big == _draws()
