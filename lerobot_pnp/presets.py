"""The task as plain data: the env's names and the named presets of its task fields.

Importable with no simulator and no LeRobot (``env_config`` holds the config class that resolves and validates
these values; a field's meaning is its comment there). ``PRESETS`` are what ``--env.preset`` names.
"""

from __future__ import annotations

import math
from typing import Any

ENV_TYPE = "baxter_pnp"  # LeRobot's env type (``--env.type=baxter_pnp``) and the type of a recorded task
GYM_NAMESPACE = "lerobot_pnp"
GYM_TASK = "BaxterPnP-v0"
GYM_ID = f"{GYM_NAMESPACE}/{GYM_TASK}"
CONTROL_MODES = ("keyframe", "dense")

# The task fields and their values in each preset (fields not listed keep the "paper" value). What each field
# means is the comment on its BaxterPnPEnvConfig field (the one description, shown by every --help).
PAPER_TASK: dict[str, Any] = {
    "object_low": (0.45, 0.10),
    "object_high": (0.75, 0.50),
    "object_exclude_low": (0.0, 0.0),
    "object_exclude_high": (0.0, 0.0),
    "yaw_range": (0.0, 0.0),
    "place_low": (0.60, -0.05),
    "place_high": (0.60, -0.05),
    "start_low": (0.45, 0.0, 0.05),
    "start_high": (0.75, 0.45, 0.25),
    "hover_height": 0.15,
    "success_xy_tol": 0.02,
    "size_range": (0.05, 0.05),
    "mass_range": (0.5, 0.5),
    "friction_range": (1.0, 1.0),
    "observe_yaw": False,
    "observe_goal": False,
    "observe_phase": False,
    "keyframe_budget": 10,
    # Perturbations (each named, seeded, usable alone; see task.PickPlaceTask.after_step).
    "nudge_max": 0.0,
    "nudge_at_step": 1,
    "grasp_miss_prob": 0.0,
    "drop_prob": 0.0,
    "displace_prob": 0.0,
    "obs_noise_object": 0.0,
    "obs_noise_joints": 0.0,
    "obs_bias_object": 0.0,
    "obs_latency": 0,
    # Perturbations as distributions (disturbances.py); these values are the original single triggers, so a
    # task recorded before they existed keeps its meaning. Times are fractions of a kind's window; 0 = the
    # original trigger at the end of a step, > 0 = in the middle of a move (see disturbances.py).
    "nudge_last_step": 0,
    "grasp_miss_window": (0.0, 0.0),
    "grasp_miss_range": (0.055, 0.07),
    "grasp_miss_max_events": 1,
    "drop_window": (0.0, 0.0),
    "drop_range": (0.08, 0.12),
    "drop_spread": 0.0,
    "drop_max_events": 1,
    "displace_window": (0.0, 0.0),
    "displace_range": (0.04, 0.08),
    "displace_spread": 1.0471975511965976,
    "displace_max_events": 1,
    "landing_low": (0.0, 0.0),
    "landing_high": (0.0, 0.0),
    "obs_latency_max": 0,
    "obs_latency_jitter": 0.0,
    "carry_min_time": 0.0,
    # Visual variation (sim/visual.py): what a camera sees, never the physics. Each is the (min, max) deviation from
    # the scene as modelled, drawn per episode from a generator of its own; (0, 0) is the scene as modelled.
    "light_intensity_range": (0.0, 0.0),
    "light_direction_range": (0.0, 0.0),
    "light_color_range": (0.0, 0.0),
    "cube_hue_range": (0.0, 0.0),
    "target_hue_range": (0.0, 0.0),
    "table_hue_range": (0.0, 0.0),
    "camera_shift_range": (0.0, 0.0),
    "camera_tilt_range": (0.0, 0.0),
    "wrist_camera_shift_range": (0.0, 0.0),
    "wrist_camera_tilt_range": (0.0, 0.0),
    "distractors_range": (0, 0),
    "image_noise_range": (0.0, 0.0),
    "image_blur_range": (0.0, 0.0),
}
# The reachable table region (IK gripper-down at hover and grasp height, any grasp yaw, clear of the table edge):
# where a disturbed object may land in `full` so that a recovery may begin anywhere the arm can re-pick it.
REACHABLE_LOW, REACHABLE_HIGH = (0.45, -0.15), (0.75, 0.60)
# Narrow perturbations: each one trigger at one moment with one size (the paper defaults of the distribution
# fields). `{**FULL_TASK, **NARROW_FULL_DISTURBANCES}` is `full` with every disturbance narrowed that way.
NARROW_FULL_DISTURBANCES: dict[str, Any] = {
    k: PAPER_TASK[k]
    for k in PAPER_TASK
    if k.startswith(("grasp_miss_", "drop_", "displace_", "landing_", "obs_latency_", "carry_"))
    and not k.endswith("_prob")
}
# `full`: everything on (a benchmark that a lookup table cannot pass; the expert recovers from all of it). Its
# perturbations are the training condition of the held-out-disturbance protocol (sim/suites.py): each at any
# moment of the first half of its window, landing anywhere reachable; held-out suites go beyond it.
FULL_TASK: dict[str, Any] = {
    **PAPER_TASK,
    "yaw_range": (-3.141592653589793, 3.141592653589793),
    "place_low": (0.50, -0.20),
    "place_high": (0.70, -0.05),
    "size_range": (0.045, 0.055),
    "mass_range": (0.3, 0.8),
    "friction_range": (0.7, 1.2),
    "observe_yaw": True,
    "observe_goal": True,
    "keyframe_budget": 40,
    "nudge_max": 0.03,
    "grasp_miss_prob": 0.25,
    "drop_prob": 0.25,
    "displace_prob": 0.25,
    "obs_noise_object": 0.003,
    "obs_noise_joints": 0.005,
    "obs_bias_object": 0.003,
    "obs_latency": 0,
    "grasp_miss_window": (0.0, 0.5),
    "grasp_miss_range": (0.055, 0.08),
    "drop_window": (0.0, 0.5),
    "drop_range": (0.08, 0.15),
    "drop_spread": math.pi,
    "displace_window": (0.0, 0.5),
    "displace_range": (0.04, 0.10),
    "displace_spread": math.pi,
    "landing_low": REACHABLE_LOW,
    "landing_high": REACHABLE_HIGH,
    "carry_min_time": 0.5,
}
# The training ranges of the visual held-out axes (sim/visual_suites.py holds the held-out ranges beyond them):
# a few degrees and millimetres, slight tints and hue shifts, at most one distractor, faint sensor noise. A camera
# policy of those axes trains on `full` with these (configs/generate_full_visual.json).
VISUAL_TRAINING: dict[str, Any] = {
    "light_intensity_range": (0.0, 0.4),  # intensity x 0.76 .. 1.32
    "light_direction_range": (0.0, 0.17),  # up to 10 degrees
    "light_color_range": (0.0, 0.15),
    "cube_hue_range": (0.0, 0.04),  # up to 14 degrees of hue
    "target_hue_range": (0.0, 0.04),
    "table_hue_range": (0.0, 0.04),
    "camera_shift_range": (0.0, 0.005),  # up to 5 mm
    "camera_tilt_range": (0.0, 0.035),  # up to 2 degrees
    "wrist_camera_shift_range": (0.0, 0.002),  # up to 2 mm
    "wrist_camera_tilt_range": (0.0, 0.017),  # up to 1 degree
    "distractors_range": (0, 1),
    "image_noise_range": (0.0, 0.02),  # std up to 2 % of full scale
    "image_blur_range": (0.0, 0.5),  # std up to half a pixel
}
PRESETS: dict[str, dict[str, Any]] = {"paper": PAPER_TASK, "full": FULL_TASK}
TASK_FIELDS = tuple(PAPER_TASK)
# The observation setup (not part of any preset): rendered cameras and their image size. Like the control mode it
# is read back from the recorded task, so a policy trained on camera images is evaluated with the same cameras.
OBSERVATION_DEFAULTS: dict[str, Any] = {"cameras": [], "image_height": 240, "image_width": 320, "render_effects": False}
# What a task recorded before an observation field existed was rendered with (the recorded-task rule: a missing field
# has its old value): MuJoCo's default visuals, shadows, reflections and multisampling.
OBSERVATION_UNRECORDED: dict[str, Any] = {"render_effects": True}
CAMERAS = ("front", "overhead", "wrist")  # the named cameras of the MJCF scene (envs/baxter_pnp.xml)
