"""Inside a stock ``lerobot-train`` process on our task only: hooks on how that script builds its training dataset.

Each hook acts only for a run on our policy, env or data (``stock_checkpoints.run_config_is_ours``); any other
run sees LeRobot's functions unchanged.

**The recorded task, checked at start-up.** A dataset that records an invalid task (``meta/baxter_pnp_env.json``
with a NaN, an unknown field ...) is refused in one line before the dataset is loaded (``check_recorded_task``),
not at the first checkpoint, which copies it.

**Per-frame phase labels for the recovering policy.** The fast path gives ``pnp_lstm`` each episode's
``phase.index`` / ``phase.subtask`` labels, which the recovering mode needs for a late episode's blind frames
(the start of a recovery it cannot see yet: out of the loss), for retiming a recovery
(``latency_augment_stretch``) and for its phase and subtask cross-entropies. Stock ``lerobot-train`` gave it
none: LeRobot windows only ``observation.*``, ``action`` and the reward (``resolve_delta_timestamps`` reads
the policy's three ``*_delta_indices``), and its processor pipeline (``batch_to_transition``) drops any other
column. So, for a recovering ``pnp_lstm`` on a dataset with those columns: ``phase_windows`` gives them the
action's window (map-style and streaming), ``labels_kept`` makes the pre-processor pass them through (as
complementary data, moved to the device with the rest), and ``stream_labels_as_arrays`` reads them from a
stream as 0-d arrays (LeRobot's stream keeps a scalar column as Python ints, which it cannot stack into a
window; the map is a step of the stream itself, so its DataLoader workers, spawned fresh, apply it too).
The clocked mode is left as it was: it reads no labels, and windowing them would only add to its loading.

**A stream LeRobot would leave empty.** LeRobot 0.6.1's ``make_dataset`` builds a ``StreamingLeRobotDataset``
with ``max_num_shards=cfg.num_workers``, and the stream reads ``min(parquet files, max_num_shards)`` shards:
with ``--num_workers 0`` it has none, yields nothing, and the first ``next(dl_iter)`` of the training loop ends
in a bare ``StopIteration`` (or accelerate's "Batch does not contain any data") once the dataset and policy are
built. The cause is LeRobot's, so its loading is not changed: ``check_stream`` raises a ``ConfigError``
(printed as one line by ``stock_errors.install_cli_excepthook``) naming the fix when a stream it returns has no
shard. It reads the stream, not the flags, so it stays silent once LeRobot gives such a stream a shard.
"""

from __future__ import annotations

import functools
import importlib
import sys
from collections.abc import Callable

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.stock_checkpoints import TRAIN_MODULE, dataset_root, run_config_is_ours

FACTORY_MODULE = "lerobot.datasets.factory"


def install_stock_train_hooks() -> bool:
    """Wrap how ``lerobot-train`` builds its datasets and pre-processor, when this process runs it; True when the
    hooks are in place. Each wrapper calls LeRobot's function first; installing twice wraps once."""
    if sys.modules.get(TRAIN_MODULE) is None:
        return False
    _wrap_once(TRAIN_MODULE, "make_train_eval_datasets", _prepared)
    _wrap_once(FACTORY_MODULE, "resolve_delta_timestamps", _with_phase_windows)
    _wrap_once(TRAIN_MODULE, "make_pre_post_processors", _with_labels_kept)
    return True


def _wrap_once(module_name: str, name: str, make: Callable[[Callable], Callable]) -> None:
    module = importlib.import_module(module_name)
    original = getattr(module, name)
    if getattr(original, "pnp_hook", False):
        return
    wrapper = functools.wraps(original)(make(original))
    wrapper.pnp_hook = True
    setattr(module, name, wrapper)


def _prepared(original):
    def make_train_eval_datasets(cfg, *args, **kwargs):
        if not run_config_is_ours(cfg):
            return original(cfg, *args, **kwargs)
        check_recorded_task(cfg)
        datasets = original(cfg, *args, **kwargs)
        for dataset in datasets if isinstance(datasets, tuple) else (datasets,):
            check_stream(dataset, getattr(cfg, "num_workers", None))
            stream_labels_as_arrays(dataset)
        return datasets

    return make_train_eval_datasets


def check_recorded_task(cfg) -> None:
    """The task the run's dataset records, validated before anything is loaded (a ``ConfigError`` naming the
    file): every checkpoint copies it, so an invalid one would otherwise stop the run at its first checkpoint."""
    from lerobot_pnp.recorded_task import dataset_task

    root = dataset_root(cfg)
    if root is not None:
        dataset_task(root)


def _with_phase_windows(original):
    def resolve_delta_timestamps(cfg, ds_meta):
        return phase_windows(cfg, ds_meta, original(cfg, ds_meta))

    return resolve_delta_timestamps


def _with_labels_kept(original):
    def make_pre_post_processors(*args, **kwargs):
        preprocessor, postprocessor = original(*args, **kwargs)
        if _recovering(kwargs.get("policy_cfg", args[0] if args else None)):
            preprocessor.to_transition = labels_kept(preprocessor.to_transition)
        return preprocessor, postprocessor

    return make_pre_post_processors


def _recovering(cfg) -> bool:
    from lerobot_pnp.policy import PnpLstmConfig

    return isinstance(cfg, PnpLstmConfig) and cfg.recovering


def _label_keys() -> tuple[str, str]:
    from lerobot_pnp.policy.modeling_pnp_lstm import PHASE_KEY, SUBTASK_KEY

    return PHASE_KEY, SUBTASK_KEY


def phase_windows(cfg, ds_meta, delta_timestamps: dict[str, list] | None) -> dict[str, list] | None:
    """``delta_timestamps`` with the phase labels windowed as the action, for a recovering ``pnp_lstm``."""
    from lerobot.utils.constants import ACTION

    if not _recovering(cfg) or not delta_timestamps or ACTION not in delta_timestamps:
        return delta_timestamps
    labels = {key: list(delta_timestamps[ACTION]) for key in _label_keys() if key in ds_meta.features}
    return {**labels, **delta_timestamps}


def labels_kept(to_transition: Callable) -> Callable:
    """A pre-processor's batch converter that also carries the phase labels (complementary data, as ``*_is_pad``)."""
    from lerobot.processor import TransitionKey

    def batch_to_transition(batch: dict) -> dict:
        transition = to_transition(batch)
        labels = {key: batch[key] for key in _label_keys() if key in batch}
        if labels:
            extra = transition.get(TransitionKey.COMPLEMENTARY_DATA) or {}
            transition[TransitionKey.COMPLEMENTARY_DATA] = {**extra, **labels}
        return transition

    return batch_to_transition


def stream_labels_as_arrays(dataset) -> None:
    """A LeRobot stream that windows the phase labels reads them as 0-d arrays (it stacks arrays, not ints)."""
    from lerobot.datasets.streaming_dataset import StreamingLeRobotDataset

    windowed = [key for key in _label_keys() if key in (getattr(dataset, "delta_timestamps", None) or {})]
    if isinstance(dataset, StreamingLeRobotDataset) and windowed:
        dataset.hf_dataset = dataset.hf_dataset.map(_labels_as_arrays, fn_kwargs={"keys": windowed})


def _labels_as_arrays(row: dict, keys: list[str]) -> dict:
    import numpy as np

    return {key: np.asarray(row[key]) for key in keys}


def check_stream(dataset, num_workers: int | None) -> None:
    """Raise ``ConfigError`` when ``dataset`` is a LeRobot stream with no shard to read (it would yield nothing)."""
    from lerobot.datasets.streaming_dataset import StreamingLeRobotDataset

    if isinstance(dataset, StreamingLeRobotDataset) and dataset.num_shards < 1:
        raise ConfigError(
            f"--dataset.streaming=true with --num_workers {num_workers} gives an empty stream (LeRobot splits the "
            "stream into num_workers shards): pass --num_workers 1 or more, or --dataset.streaming=false"
        )
