"""Expert demonstrations as a LeRobotDataset v3.0 (``lerobot-pnp generate`` / ``lerobot-pnp push``).

Everything is written with LeRobot's own writer (``LeRobotDataset.create / add_frame / save_episode /
finalize``), run as datatrove tasks and merged with LeRobot's ``aggregate_datasets``; the result is a plain
LeRobot folder that the stock loader, ``lerobot-train`` and ``lerobot-dataset-viz`` read, with the env
config it was made with in ``meta/baxter_pnp_env.json``.

Modules, one job each: ``schema`` (the feature spec), ``episodes`` (slot seeds, expert episode -> frames),
``shards`` (the datatrove step writing one shard), ``merge`` (aggregate, verify, split, commit),
``executors`` (local / SLURM runs, progress), ``workdir`` (root layout, lock, what may be deleted),
``generation`` (``GenerateConfig``, ``generate``), ``validation`` (read-side checks, opener, hash), ``splits``
(the train/test split: parser, train-fraction rule), ``layout`` (the meta file paths, the JSON reader),
``hub`` (``push``).
"""

from lerobot_pnp.dataset.executors import SlurmOptions
from lerobot_pnp.dataset.generation import GenerateConfig, generate
from lerobot_pnp.dataset.hub import PushConfig, push
from lerobot_pnp.dataset.schema import ROBOT_TYPE, dataset_features
from lerobot_pnp.dataset.splits import load_split
from lerobot_pnp.dataset.validation import (
    data_hash,
    episode_seeds,
    open_local_dataset,
    validate_dataset,
    verify_dataset,
)

__all__ = [
    "ROBOT_TYPE",
    "GenerateConfig",
    "PushConfig",
    "SlurmOptions",
    "data_hash",
    "dataset_features",
    "episode_seeds",
    "generate",
    "load_split",
    "open_local_dataset",
    "push",
    "validate_dataset",
    "verify_dataset",
]
