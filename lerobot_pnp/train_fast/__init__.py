"""Fast training path for the ``pnp_lstm`` planner: whole keyframe episodes as tensors, no DataLoader.

A keyframe dataset is tiny (1400 episodes x 10 frames in the paper), so this loads every episode once as
``(E, 10, D)`` tensors, normalises them with the same LeRobot pre-processor, and trains the *same*
``PnpLstmPolicy`` on batches of whole episodes. It writes:

* ``<output_dir>/checkpoints/<step>/pretrained_model/`` in ``lerobot-train``'s layout (config.json,
  model.safetensors, train_config.json, policy_{pre,post}processor.json + stats), a ``training_state/``
  next to it and the ``checkpoints/last`` link, so ``lerobot-eval --policy.path=.../pretrained_model``
  loads it;
* ``loss_curve.csv`` and ``loss_curve.png``: train vs held-out MSE (normalised actions) per epoch, the
  paper's Fig. 4;
* ``test_keyframe_error.json``: per-joint held-out error of the predicted next keyframe, in degrees;
* ``train_fast_config.json``: the config of the run.

The train/test split is read from the dataset's ``meta/info.json`` ``splits`` (``{"train": "0:1120",
"test": "1120:1400"}``); without a test split the last 20 % of the episodes are held out
(``lerobot_pnp.dataset.splits.train_test``).

Modules: ``config`` (the validated config), ``data`` (load, check, split), ``loop`` (training and
checkpoints), ``output`` (the output folder: held for the run; ``--overwrite`` replaces what a training run wrote
there), ``summary`` (held-out keyframe error, loss curve).

Library use::

    from lerobot_pnp.train_fast import TrainFastConfig, train_fast
    result = train_fast(TrainFastConfig(dataset_root="data/keyframes", epochs=300))

Command line: ``lerobot-pnp train --dataset_root=... --epochs=300 --policy.hidden_size=64``.
"""

from .config import TrainFastConfig, normalize_episode_range, policy_config_from_dict
from .data import KeyframeData, load_keyframe_data, validate_keyframe_dataset
from .loop import TrainFastResult, train_fast
from .summary import keyframe_error

__all__ = [
    "KeyframeData",
    "TrainFastConfig",
    "TrainFastResult",
    "keyframe_error",
    "load_keyframe_data",
    "normalize_episode_range",
    "policy_config_from_dict",
    "train_fast",
    "validate_keyframe_dataset",
]
