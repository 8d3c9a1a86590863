"""The visual variation of an episode applied to the MuJoCo model at reset (``visual`` draws it).

``SceneVariation`` remembers the scene as modelled (the lights, the headlight, the three materials, the cameras)
and at every reset writes the episode's variation over it through the model's fields: ``light_diffuse`` /
``light_specular`` / ``light_pos`` / ``light_dir``, ``vis.headlight``, ``mat_rgba``, ``cam_pos`` / ``cam_quat``,
and the distractors' ``body_pos`` / ``body_quat`` / ``geom_group``. Nothing is recompiled, and the physics reads
none of these fields, so the episode's dynamics are those of the scene as modelled. It is written before the
physics' reset, whose forward pass computes the cameras' and lights' world poses from them.

The episode's generators are spawned from the env's (``Generator.spawn`` draws nothing from it): one for the
episode's variation and the distractors' places, one for the images' noise frame by frame.
"""

from __future__ import annotations

import colorsys

import numpy as np

from lerobot_pnp import robot
from lerobot_pnp.sim import distractors, visual
from lerobot_pnp.sim.image_noise import degrade

SCENE_CENTRE = np.array([0.6, 0.2, robot.TABLE_TOP_Z])  # the lights turn about this point of the table
MATERIALS = ("cube", "target", "table")


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ])  # fmt: skip


def shifted_hue(rgba: np.ndarray, shift: float) -> np.ndarray:
    """``rgba`` with its hue turned by ``shift`` of the circle (saturation, value and alpha kept)."""
    h, s, v = colorsys.rgb_to_hsv(*rgba[:3])
    return np.array([*colorsys.hsv_to_rgb((h + shift) % 1.0, s, v), rgba[3]])


class SceneVariation:
    """A config's visual variation on one physics' model, drawn and applied per episode."""

    def __init__(self, config, physics):
        self.config = config
        m = physics.model
        self.model = m
        self._light = {k: getattr(m, f"light_{k}").copy() for k in ("diffuse", "specular", "pos", "dir")}
        head = m.vis.headlight
        self._headlight = {k: np.array(getattr(head, k), dtype=float) for k in ("ambient", "diffuse", "specular")}
        self._materials = {name: m.mat(name).id for name in MATERIALS}
        self._mat_rgba = {name: m.mat_rgba[i].copy() for name, i in self._materials.items()}
        self._cameras = {name: m.camera(name).id for name in (*visual.MOVED_CAMERAS, "wrist")}
        self._cam = {name: (m.cam_pos[i].copy(), m.cam_quat[i].copy()) for name, i in self._cameras.items()}
        self._slots = config.distractors_range[1]
        self._distractor_slots = distractors.slot_ids(m, self._slots)
        self.sample: visual.VisualSample | None = None
        self._noise_rng: np.random.Generator | None = None

    def reset(self, rng: np.random.Generator, object_xy, place_xy) -> visual.VisualSample:
        """Draw the episode's variation from generators spawned from ``rng`` and write it into the model."""
        episode, self._noise_rng = rng.spawn(2)
        sample = self.sample = visual.draw(self.config, episode)
        self._lights(sample)
        for name, i in self._materials.items():
            self.model.mat_rgba[i] = shifted_hue(self._mat_rgba[name], sample.hue_shift[name])
        for name, i in self._cameras.items():
            pos, quat = self._cam[name]
            offset = sample.cameras[name]
            self.model.cam_pos[i] = pos + offset.shift
            self.model.cam_quat[i] = _quat_mul(quat, offset.turn)
        if self._slots:
            yaw = episode.uniform(0, 2 * np.pi, self._slots)
            spots = distractors.place(episode, sample.distractors, object_xy, place_xy)
            distractors.show(self.model, self._distractor_slots, spots, yaw)
        return sample

    def _lights(self, sample: visual.VisualSample) -> None:
        m, gain = self.model, sample.intensity * sample.tint
        m.light_diffuse[:] = np.clip(self._light["diffuse"] * gain, 0, None)
        m.light_specular[:] = np.clip(self._light["specular"] * gain, 0, None)
        m.light_pos[:] = SCENE_CENTRE + (self._light["pos"] - SCENE_CENTRE) @ sample.light_turn.T
        m.light_dir[:] = self._light["dir"] @ sample.light_turn.T
        for k, value in self._headlight.items():
            setattr(m.vis.headlight, k, np.clip(value * gain, 0, None))

    def images(self, pixels: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The rendered images as the episode's sensor returns them (blur, then noise redrawn every frame)."""
        s = self.sample
        if s is None or (s.noise_std <= 0 and s.blur_sigma <= 0):
            return pixels
        return {cam: degrade(img, s.blur_sigma, s.noise_std, self._noise_rng) for cam, img in pixels.items()}
