"""The viewer shows what a camera policy sees: each frame it received and the keypoints it computed on it.

A tiny untrained ``pnp_pixels`` checkpoint recording a two-camera task at 32x32 is rolled out by ``visualize``;
the .rrd is read back with Rerun's own reader. The keypoints come from the policy's own forward pass (checked
against the encoder run on the logged image), in pixel coordinates with x along the columns.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig, make_env

SIZE, KEYPOINTS, CAMERAS = 32, 4, ("front", "wrist")


def _task() -> BaxterPnPEnvConfig:
    return BaxterPnPEnvConfig(preset="full", cameras=list(CAMERAS), image_height=SIZE, image_width=SIZE)


@pytest.fixture(scope="module")
def pixels_checkpoint(tmp_path_factory) -> Path:
    """A tiny untrained pnp_pixels checkpoint with its processors and the camera task it records."""
    import torch
    from lerobot.configs.types import FeatureType, PolicyFeature

    from lerobot_pnp.integration.recorded_task import write_checkpoint_task
    from lerobot_pnp.policy import PnpPixelsConfig, PnpPixelsPolicy
    from lerobot_pnp.policy.processor_pnp_pixels import make_pnp_pixels_pre_post_processors

    task = _task()
    env = make_env(task, render_mode=None)
    env_dim = int(env.reset(seed=0)[0]["environment_state"].shape[0])
    env.close()
    cfg = PnpPixelsConfig(hidden_size=16, conv_channels=[8, 8], num_keypoints=KEYPOINTS)
    cfg.input_features = {
        "observation.state": PolicyFeature(type=FeatureType.STATE, shape=(8,)),
        "observation.environment_state": PolicyFeature(type=FeatureType.ENV, shape=(env_dim,)),
        **{
            f"observation.images.{cam}": PolicyFeature(type=FeatureType.VISUAL, shape=(3, SIZE, SIZE))
            for cam in CAMERAS
        },
    }
    cfg.output_features = {"action": PolicyFeature(type=FeatureType.ACTION, shape=(8,))}
    stats = {
        key: {"mean": np.zeros(dim, np.float32), "std": np.ones(dim, np.float32)}
        for key, dim in (("observation.state", 8), ("observation.environment_state", env_dim), ("action", 8))
    }
    path = tmp_path_factory.mktemp("viz_cameras") / "pretrained_model"
    torch.manual_seed(0)
    PnpPixelsPolicy(cfg).save_pretrained(path)
    pre, post = make_pnp_pixels_pre_post_processors(cfg, stats)
    pre.save_pretrained(path)
    post.save_pretrained(path)
    write_checkpoint_task(task.to_dict(), path)
    return path


def _rows(path: Path, entity: str) -> dict:
    from rerun.experimental import RrdReader

    rows: list[dict] = []  # one per logged row; a component a row did not log is missing from it
    for chunk in RrdReader(path).store().stream().to_chunks():
        if chunk.entity_path != entity or chunk.is_static or "frame_index" not in chunk.timeline_names:
            continue
        columns = chunk.to_record_batch().to_pydict()
        rows += [{k: v[i] for k, v in columns.items()} for i in range(len(columns["frame_index"]))]
    rows.sort(key=lambda row: row["frame_index"])
    return {k: [row.get(k) for row in rows] for k in {k for row in rows for k in row}}


def test_camera_frames_and_keypoints_are_logged(pixels_checkpoint, tmp_path):
    import torch

    from lerobot_pnp.evaluation.checkpoints import load_policy
    from lerobot_pnp.viz import VizConfig, visualize

    out = tmp_path / "cams.rrd"
    run = visualize(VizConfig(policy_path=str(pixels_checkpoint), compare_expert=False, save=str(out)))["runs"][0]
    steps = run["steps"]
    assert steps >= 1
    encoders = load_policy(str(pixels_checkpoint)).policy.encoders
    for cam, encoder in zip(CAMERAS, encoders, strict=True):
        images = _rows(out, f"/rollout_0/cameras/{cam}")
        points = _rows(out, f"/rollout_0/cameras/{cam}/keypoints")
        assert images["frame_index"] == list(range(steps + 1))  # every observation, the last one included
        assert points["frame_index"] == list(range(steps + 1))
        *acted, final = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in points["Points2D:positions"]]
        assert len(final) == 0  # the policy did not act on the final observation: its last points are cleared
        xy = np.array(acted)
        assert xy.shape == (steps, KEYPOINTS, 2)
        assert np.all((xy > 0) & (xy < SIZE))
        colors = [list(c) for c in points["Points2D:colors"][:steps]]
        assert len(colors[0]) == KEYPOINTS and len(set(colors[0])) == KEYPOINTS
        assert all(c == colors[0] for c in colors)  # one colour per keypoint, the same every step
        # the logged points are what the policy's encoder computes on the logged image
        fmt = images["Image:format"][0][0]
        assert (fmt["height"], fmt["width"]) == (SIZE, SIZE)
        first = np.frombuffer(bytes(np.asarray(images["Image:buffer"][0][0], np.uint8)), np.uint8)
        image = torch.from_numpy(first.reshape(SIZE, SIZE, 3).copy()).permute(2, 0, 1)[None].float() / 255
        with torch.no_grad():
            expected = encoder.pixel_coordinates(encoder(image))[0].numpy()
        np.testing.assert_allclose(xy[0], expected, atol=1e-4)


def _receptive_field_centroid(encoder, size: int, row: int, col: int) -> list[float]:
    """(column, row) centroid, in image pixel indices, of what map cell (row, col) sees: the gradient of that cell
    through the encoder's own maps (pooling included) with every conv weight equal."""
    import torch

    for m in encoder.conv:
        if isinstance(m, torch.nn.Conv2d):
            torch.nn.init.constant_(m.weight, 0.01)
            torch.nn.init.zeros_(m.bias)
    image = torch.ones(1, 3, size, size, requires_grad=True)
    encoder.eval().feature_maps(image)[0, 0, row, col].backward()
    weight = image.grad[0].sum(0)
    index = torch.arange(size, dtype=torch.float32)
    return [
        float((weight.sum(0) * index).sum() / weight.sum()),
        float((weight.sum(1) * index).sum() / weight.sum()),
    ]


def test_keypoint_pixels_put_x_on_the_columns():
    """A map peaked at cell (row r, column c) gives the keypoint on image pixel (row stride*r, column stride*c)."""
    import torch

    from lerobot_pnp.policy.image_encoder import KeypointEncoder

    encoder = KeypointEncoder((3, SIZE, SIZE), [8, 8], num_keypoints=2)
    h, w = encoder.map_shape
    assert (h, w, encoder.stride) == (8, 8, 4)
    maps = torch.full((1, 2, h, w), -1e4)
    maps[0, 0, 1, 6] = 0.0  # row 1, column 6
    maps[0, 1, 7, 0] = 0.0  # row 7, column 0
    with torch.no_grad():
        xy = encoder.pixel_coordinates(encoder.softmax(maps))[0].numpy()
    np.testing.assert_allclose(xy, [[6 * 4 + 0.5, 1 * 4 + 0.5], [0.5, 7 * 4 + 0.5]], atol=1e-4)
    # ... which is the centre of what that map cell sees: the centroid of its receptive field in the image
    centroid = _receptive_field_centroid(encoder, SIZE, 2, 5)  # an inner cell: row 2, column 5
    maps = torch.full((1, 2, h, w), -1e4)
    maps[0, :, 2, 5] = 0.0
    with torch.no_grad():
        xy = encoder.pixel_coordinates(encoder.softmax(maps))[0, 0].numpy()
    np.testing.assert_allclose(xy - 0.5, centroid, atol=1e-4)  # pixel index i is drawn at i + 0.5


def test_keypoint_pixels_of_a_pooled_encoder_are_the_centres_of_what_their_cells_see():
    """With the image average-pooled by 2 first, a map cell covers twice the image pixels: the keypoint of a map
    peaked on an inner cell lands on the centroid of that cell's receptive field in the full-size image."""
    import torch

    from lerobot_pnp.policy.image_encoder import KeypointEncoder

    size = 2 * SIZE  # an inner cell's receptive field lies inside the image
    encoder = KeypointEncoder((3, size, size), [8, 8], num_keypoints=1, pool=2)
    h, w = encoder.map_shape
    assert (h, w, encoder.stride) == (size // 8, size // 8, 8)
    centroid = _receptive_field_centroid(encoder, size, 2, 5)  # row 2, column 5
    maps = torch.full((1, 1, h, w), -1e4)
    maps[0, 0, 2, 5] = 0.0
    with torch.no_grad():
        xy = encoder.pixel_coordinates(encoder.softmax(maps))[0, 0].numpy()
    np.testing.assert_allclose(xy - 0.5, centroid, atol=1e-4)
    with torch.no_grad():  # and the encoder's own forward pools: one keypoint per camera image, in [-1, 1]
        out = encoder.eval()(torch.rand(2, 3, size, size))
    assert out.shape == (2, 2) and bool((out.abs() <= 1).all())


def test_a_policy_without_keypoint_encoders_has_none():
    from lerobot_pnp.viz.keypoints import KeypointTap, keypoint_colors

    class Plain:
        pass

    with KeypointTap(Plain()) as tap:
        tap.take()
    assert tap.per_frame == {}
    colors = keypoint_colors(25)
    assert colors.shape == (25, 3) and len({tuple(c) for c in colors}) == 25
