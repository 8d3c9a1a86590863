"""Configuration of ``pnp_pixels``: the recovering planner that sees the world through cameras only.

A sibling policy type of ``pnp_lstm`` rather than an option of it, because what it consumes differs at the level
LeRobot checks: ``pnp_lstm`` needs ``observation.environment_state`` (the cube's and target's coordinates, which
the simulator alone knows) and warns that it ignores images; ``pnp_pixels`` needs at least one camera image and
never reads the environment state when it acts. As its own type, a checkpoint says which world it was made for
(``type`` in its ``config.json``), ``lerobot-eval`` and the strict loader check its cameras against the env's, and
the state planner's config keeps its meaning. Everything else is the state planner's: the config subclasses
``PnpLstmConfig`` (the same recurrent trunk, learned switch, observation gate and recipe options, in recovering
mode by default), and the policy subclasses ``PnpLstmPolicy`` with an image encoder in front of the same planner.

Privileged supervision, training only: with ``pose_loss_weight > 0`` and a dataset that records
``observation.environment_state``, an auxiliary head predicts that (normalised) state from the image keypoints
and its MSE is added to the loss. The head's output is never used to act; at inference the policy reads the
joints and the images only (passing NaN as the environment state changes nothing).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.configs import FeatureType, NormalizationMode, PreTrainedConfig
from lerobot.utils.constants import ACTION, OBS_STATE

from lerobot_pnp.errors import ConfigError

from .configuration_pnp_lstm import PnpLstmConfig


@PreTrainedConfig.register_subclass("pnp_pixels")
@dataclass
class PnpPixelsConfig(PnpLstmConfig):
    """``pnp_lstm``'s recovering planner on joint state + camera images (see the module docstring)."""

    mode: str = "recovering"
    """As ``pnp_lstm``'s ``mode``; recovering by default (the `full` task's episodes vary in length)."""
    normalization_mapping: dict[str, NormalizationMode] = field(
        default_factory=lambda: {
            "VISUAL": NormalizationMode.IDENTITY,
            "STATE": NormalizationMode.MEAN_STD,
            "ENV": NormalizationMode.MEAN_STD,
            "ACTION": NormalizationMode.MEAN_STD,
        }
    )
    """Images pass as they are (the encoder scales them); the environment state is normalised as the auxiliary
    target it is."""
    conv_channels: list[int] = field(default_factory=lambda: [16, 32])
    """Channels of the encoder's conv layers, each halving the resolution (the first 5x5, the rest 3x3)."""
    num_keypoints: int = 16
    """Spatial-softmax keypoints per camera: the encoder gives each camera's ``2 * num_keypoints`` image
    coordinates to the planner."""
    keypoint_strength: bool = False
    """Each camera also gives each keypoint's feature value where its softmax looks (``num_keypoints`` more
    numbers): how strongly a feature fires, which carries what the positions do not, such as the cube's yaw."""
    keypoint_strength_norm: bool = False
    """With ``keypoint_strength``: normalise the strengths by batch statistics (``BatchNorm1d`` without affine
    terms, its running statistics at inference). The positions are in [-1, 1]; a map value has no scale of its
    own and may grow in training, as the net sharpens its softmax by scaling its maps."""
    image_downsample: int = 1
    """The encoder reads each image average-pooled by this factor (1: at the recorded resolution; it must divide
    the image's height and width). It sets the resolution the policy works at apart from the one the benchmark
    renders, which is part of the recorded task."""
    image_shift: int = 4
    """Training only: each image shifted by a random whole number of pixels up to this in x and y (0: off)."""
    pose_loss_weight: float = 0.1
    """Training only: weight of the auxiliary MSE of the normalised ``observation.environment_state`` predicted
    from the keypoints, where the batch carries it (0: off; the policy then never looks at that feature)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            (
                len(self.conv_channels) >= 1 and all(isinstance(c, int) and c >= 1 for c in self.conv_channels),
                f"conv_channels must be one or more positive integers, got {list(self.conv_channels)}",
            ),
            (self.num_keypoints >= 1, f"num_keypoints must be >= 1, got {self.num_keypoints}"),
            (
                self.keypoint_strength or not self.keypoint_strength_norm,
                "keypoint_strength_norm normalises the keypoint strengths: it needs keypoint_strength true",
            ),
            (self.image_shift >= 0, f"image_shift must be >= 0, got {self.image_shift}"),
            (self.image_downsample >= 1, f"image_downsample must be >= 1, got {self.image_downsample}"),
            (self.pose_loss_weight >= 0, f"pose_loss_weight must be >= 0, got {self.pose_loss_weight}"),
        ]
        for ok, message in checks:
            if not ok:
                raise ConfigError(f"policy.{message}")

    def validate_features(self) -> None:
        """Joint state, at least one camera and the action; the environment state is optional (training target)."""
        inputs = self.input_features or {}
        state = inputs.get(OBS_STATE)
        if state is None or state.type is not FeatureType.STATE:
            raise ConfigError(
                f"pnp_pixels needs the input feature '{OBS_STATE}' (robot joints + gripper); "
                f"got input features {sorted(inputs)}"
            )
        if not self.image_features:
            raise ConfigError(
                "pnp_pixels needs at least one camera image (observation.images.<camera>): generate the dataset "
                f"with --env.cameras, e.g. '[front]'; got input features {sorted(inputs)}"
            )
        if ACTION not in (self.output_features or {}):
            raise ConfigError(f"pnp_pixels needs the output feature '{ACTION}'; got {sorted(self.output_features)}")
        shapes = {tuple(ft.shape) for ft in self.image_features.values()}
        if len(shapes) != 1 or len(next(iter(shapes))) != 3:
            raise ConfigError(f"pnp_pixels needs its cameras' images of one size (C, H, W); got {sorted(shapes)}")
        _, h, w = next(iter(shapes))
        if h % self.image_downsample or w % self.image_downsample or h < 8 * self.image_downsample:
            raise ConfigError(
                f"policy.image_downsample={self.image_downsample} must divide the images' {h}x{w} and leave at "
                "least 8 pixels a side"
            )
        for key, ft in {**inputs, **(self.output_features or {})}.items():
            if ft.type is not FeatureType.VISUAL and len(ft.shape) != 1:
                raise ConfigError(f"pnp_pixels expects 1-D features; '{key}' has shape {tuple(ft.shape)}")

    @property
    def model_input_keys(self) -> list[str]:
        """The non-image features the planner reads: the robot state only (never the environment state)."""
        inputs = self.input_features or {}
        return sorted(k for k, ft in inputs.items() if ft.type is FeatureType.STATE)

    @property
    def camera_keys(self) -> list[str]:
        """The image features the encoder reads, in a fixed order."""
        return sorted(self.image_features)
