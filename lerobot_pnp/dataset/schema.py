"""The one feature spec of a pnp dataset (LeRobot ``features`` dict), derived from the env config.

Per frame: ``observation.state`` (7 joints + gripper), ``observation.environment_state`` (object xyz [+ sin/cos 4 yaw] [+ goal xy]),
``action``, ``next.done``, ``next.success``, ``phase.index`` (FSM phase 0..9), ``phase.subtask`` (0 pick,
1 place), ``episode.seed`` (the expert seed that re-simulates the episode exactly) and the task string.
``phase.*`` and ``episode.*`` are deliberately not ``observation.*`` so LeRobot never feeds them to a policy.
Camera images, when the env renders them, are videos ``observation.images.<camera>``.
"""

from __future__ import annotations

from contextlib import contextmanager

from lerobot_pnp import robot

ROBOT_TYPE = "baxter"


def dataset_features(env=None) -> dict:
    """LeRobot feature spec for datasets recorded from ``env`` (a ``BaxterPnPEnvConfig``; None = no cameras)."""
    scalar = {"shape": (1,), "names": None}
    env_state_names = env.environment_state_names if env is not None else list(robot.OBJECT_NAMES)
    features = {
        "observation.state": {"dtype": "float32", "shape": (robot.STATE_DIM,), "names": list(robot.STATE_NAMES)},
        # object xyz, then (sin 4 yaw, cos 4 yaw) and the goal xy when the task observes them
        "observation.environment_state": {
            "dtype": "float32",
            "shape": (len(env_state_names),),
            "names": env_state_names,
        },
        "action": {"dtype": "float32", "shape": (robot.ACTION_DIM,), "names": list(robot.ACTION_NAMES)},
        "next.done": {"dtype": "bool", **scalar},
        "next.success": {"dtype": "bool", **scalar},
        "phase.index": {"dtype": "int64", **scalar},
        "phase.subtask": {"dtype": "int64", **scalar},
        "episode.seed": {"dtype": "int64", **scalar},
    }
    for cam in env.cameras if env is not None else ():
        features[f"observation.images.{cam}"] = {
            "dtype": "video",
            "shape": (env.image_height, env.image_width, 3),
            "names": ["height", "width", "channels"],
        }
    return features


@contextmanager
def saves_without_image_embedding(features: dict):
    """While open, LeRobot's ``save_episode`` skips embedding image bytes into the episode's table when the
    dataset has no ``image`` feature (state-only, or cameras stored as video files).

    LeRobot embeds them with a ``datasets.map`` over every frame of the episode
    (``lerobot.datasets.io_utils.embed_images``, called by its writer whatever the features), which costs more
    than simulating a control-rate episode. Without an image column the map returns the table it was given, so
    the written table and its features are the same (the file's footer only lacks the map's fingerprint; a
    generated dataset, merged from its shards, is byte for byte the same). With an image feature nothing is
    changed."""
    import lerobot.datasets.dataset_writer as writer

    original = getattr(writer, "embed_images", None)
    if original is None or any(ft.get("dtype") == "image" for ft in features.values()):
        yield
        return
    writer.embed_images = _same_table
    try:
        yield
    finally:
        writer.embed_images = original


def _same_table(dataset):
    return dataset
