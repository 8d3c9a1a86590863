"""Stock ``lerobot-train`` on a streaming dataset with ``--num_workers 0``: one line naming the fix, not a crash.

LeRobot 0.6.1's ``make_dataset`` builds a ``StreamingLeRobotDataset`` with ``max_num_shards=cfg.num_workers``,
and the stream iterates over ``min(parquet files, max_num_shards)`` shards: with 0 workers it has no shard,
yields nothing, and the first ``next(dl_iter)`` of the training loop ends in a bare ``StopIteration`` (or
accelerate's "Batch does not contain any data") after the dataset and policy have been built. The cause is
LeRobot's, so the plugin does not change its data loading; inside a ``lerobot-train`` process only, it wraps
that script's ``make_train_eval_datasets`` and raises a ``ConfigError`` (printed as one line by
``errors.install_cli_excepthook``) when a stream it returns has no shard. The check reads the stream itself,
not the flags, so it stays silent once LeRobot gives a 0-worker stream a shard of its own.
"""

from __future__ import annotations

import functools
import sys

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.stock_checkpoints import TRAIN_MODULE


def install_stream_check() -> bool:
    """Wrap ``lerobot-train``'s ``make_train_eval_datasets`` when this process runs it; True when in place."""
    module = sys.modules.get(TRAIN_MODULE)
    original = getattr(module, "make_train_eval_datasets", None)
    if original is None:
        return False
    if getattr(original, "checks_pnp_stream", False):
        return True

    @functools.wraps(original)
    def make_train_eval_datasets(cfg, *args, **kwargs):
        datasets = original(cfg, *args, **kwargs)
        for dataset in datasets if isinstance(datasets, tuple) else (datasets,):
            check_stream(dataset, getattr(cfg, "num_workers", None))
        return datasets

    make_train_eval_datasets.checks_pnp_stream = True
    module.make_train_eval_datasets = make_train_eval_datasets
    return True


def check_stream(dataset, num_workers: int | None) -> None:
    """Raise ``ConfigError`` when ``dataset`` is a LeRobot stream with no shard to read (it would yield nothing)."""
    from lerobot.datasets.streaming_dataset import StreamingLeRobotDataset

    if isinstance(dataset, StreamingLeRobotDataset) and dataset.num_shards < 1:
        raise ConfigError(
            f"--dataset.streaming=true with --num_workers {num_workers} gives an empty stream (LeRobot splits the "
            "stream into num_workers shards): pass --num_workers 1 or more, or --dataset.streaming=false"
        )
