"""The spatial-softmax keypoints a camera policy computed on each frame, for the viewer's camera panels.

A keypoint encoder (``policy.image_encoder.KeypointEncoder``) turns each camera image into points where its
feature maps peak: what the planner reads of the image instead of the object's coordinates. Drawing them on the
frame they came from shows what the policy attends to. They are read from the policy's own forward pass (a
forward hook on each encoder keeps its last output), so the viewer runs no second pass and changes nothing the
policy computes or returns. A policy without such encoders (e.g. ACT on images) has its frames shown, no points.
"""

from __future__ import annotations

import colorsys

import numpy as np

KEYPOINT_RADIUS_UI = 4.0  # marker size on the camera images, in UI points (readable at any image size)
# A keypoint keeps its colour in every frame and every camera, so one point can be followed through a run.
_TAB20 = (
    (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
    (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207), (174, 199, 232), (255, 187, 120),
    (152, 223, 138), (255, 152, 150), (197, 176, 213), (196, 156, 148), (247, 182, 210), (199, 199, 199),
    (219, 219, 141), (158, 218, 229),
)  # fmt: skip


def keypoint_colors(n: int) -> np.ndarray:
    """``(n, 3)`` uint8 colours, one per keypoint index: a fixed palette, then evenly spaced hues beyond it."""
    extra = [tuple(round(255 * c) for c in colorsys.hsv_to_rgb(i / max(n, 1), 0.8, 1.0)) for i in range(n)]
    return np.array([*_TAB20, *extra][:n], dtype=np.uint8).reshape(n, 3)


def keypoint_points(xy: np.ndarray):
    """One frame's ``(K, 2)`` keypoints (pixel column, row) as Rerun points, coloured by keypoint index."""
    import rerun as rr

    n = len(xy)
    return rr.Points2D(
        xy,
        colors=keypoint_colors(n),
        radii=rr.components.Radius.ui_points(KEYPOINT_RADIUS_UI),
        labels=[f"keypoint {i}" for i in range(n)],
        show_labels=False,
    )


def keypoint_encoders(policy) -> dict:
    """``{camera: encoder}`` for each camera the policy encodes with spatial-softmax keypoints (empty if none)."""
    from lerobot.utils.constants import OBS_IMAGES

    from lerobot_pnp.policy.image_encoder import KeypointEncoder

    keys, encoders = getattr(policy, "camera_keys", None), getattr(policy, "encoders", None)
    if not keys or encoders is None:
        return {}
    prefix = f"{OBS_IMAGES}."
    return {
        key.removeprefix(prefix): enc
        for key, enc in zip(keys, encoders, strict=False)
        if isinstance(enc, KeypointEncoder)
    }


class KeypointTap:
    """Keeps, per policy step, the keypoints each camera's encoder computed, in image pixels.

    Use as a context manager around the rollout and call ``take()`` once per step after the policy acted:
    ``per_frame[camera][k]`` is then the ``(K, 2)`` (column, row) keypoints of the image of step ``k`` (NaN
    where the encoder did not run that step). The hooks are removed on exit."""

    def __init__(self, policy):
        self.encoders = keypoint_encoders(policy)
        self.per_frame: dict[str, list[np.ndarray]] = {cam: [] for cam in self.encoders}
        self._latest: dict = {}
        self._handles: list = []

    def __enter__(self) -> KeypointTap:
        for cam, enc in self.encoders.items():
            self._handles.append(enc.register_forward_hook(self._keeper(cam)))
        return self

    def __exit__(self, *exc) -> None:
        for handle in self._handles:
            handle.remove()
        self._handles.clear()

    def _keeper(self, cam: str):
        def hook(module, inputs, output) -> None:
            # one environment in the viewer: the last row is the frame the policy is acting on
            self._latest[cam] = output.detach()[-1:]

        return hook

    def take(self) -> None:
        """Store the keypoints of the step the policy just acted on."""
        for cam, enc in self.encoders.items():
            kp = self._latest.pop(cam, None)
            if kp is None:
                self.per_frame[cam].append(np.full((enc.num_keypoints, 2), np.nan, np.float32))
            else:
                self.per_frame[cam].append(enc.pixel_coordinates(kp)[0].cpu().numpy().astype(np.float32))
