"""Rerun viewer for dataset episodes and policy rollouts (``lerobot-pnp viz``).

Modules, one job each: ``config`` (flags), ``scene`` (MuJoCo model -> Rerun geometry), ``sampling`` (the
simulation watched between frames), ``sources`` (dataset episodes replayed in their recorded task),
``rollouts`` (policy rollouts beside the FSM expert), ``keypoints`` (what a camera policy computed on each
frame), ``recording`` (what is logged, and the blueprint), ``screenshot`` (the headless viewer's picture),
``app`` (``visualize``). The viewer reads datasets, checkpoints and the env's model through public APIs only
and writes nothing back.

Entity paths (stable; ``<run>`` is ``episode_<N>`` for dataset episode N, ``rollout_<i>`` for policy rollout i)
---------------------------------------------------------------------------------------------------------
``<run>/world``                              view coordinates (right-handed, Z up; Baxter base frame)
``<run>/world/robot/<body>``                 Transform3D: world pose of a robot body (per sample)
``<run>/world/robot/<body>/<geom>``          static primitive in the body frame, coloured by arm part
``<run>/world/cube``, ``.../cube/<geom>``    the object (pose per sample)
``<run>/world/scene/<body>/<geom>``          static scene: floor, table
``<run>/world/target``                       the place target (static disc)
``<run>/world/ee``, ``<run>/world/ee_path``  end-effector position (per sample); its whole path (static)
``<run>/world/keyframes``                    Points3D: where each FSM phase was reached, one label per place
``<run>/plots/joints/<joint>``               Scalars: the 7 joint angles (rad)
``<run>/plots/gripper``                      Scalars: measured gripper opening (0 closed .. 1 open)
``<run>/plots/action/<name>``                Scalars at frames: the commanded keyframe (7 joints + gripper)
``<run>/plots/object/{x,y,z}``               Scalars: object position (m)
``<run>/plots/phase``                        TextLog: FSM phase name, at each frame a phase is entered
``<run>/plots/phase_index``                  Scalars: FSM phase index (continuous samples and frames)
``<run>/plots/success``                      Scalars 0/1: the env's success check of the simulated state
``<run>/cameras/<camera>``                   Image at frames: each camera frame the run observed
``<run>/events``                             TextLog at frames: perturbations as they fire, failure cause, success
Policy rollouts add (``<run>/world/keyframes`` of a rollout are the *predicted* keyframes):
``<run>/world/expert_keyframes``, ``<run>/world/expert_ee_path``   the FSM expert from the same start
``<run>/policy/pred/<name>``, ``<run>/policy/expert/<name>``       Scalars at frames: predicted vs expert keyframe
``<run>/policy/error/joints/<joint>``, ``.../error/gripper``       |predicted - expert| (rad; command)
``<run>/policy/error/ee_pos``                                      end-effector distance of the two keyframes (m)
``<run>/cameras/<camera>/keypoints``   Points2D at frames: a keypoint encoder's keypoints on the frame (pixels)

Timelines: ``time`` (simulated seconds since reset, every sample) and ``frame_index`` (the run's frames,
with the dataset's own values); see ``recording``.
"""

from lerobot_pnp.viz.app import visualize
from lerobot_pnp.viz.config import VizConfig
from lerobot_pnp.viz.screenshot import ScreenshotError, ViewerUnavailableError, take_screenshot
from lerobot_pnp.viz.sources import DatasetNotFoundError, EpisodeNotFoundError, IncompatibleDatasetError

__all__ = [
    "DatasetNotFoundError",
    "EpisodeNotFoundError",
    "IncompatibleDatasetError",
    "ScreenshotError",
    "ViewerUnavailableError",
    "VizConfig",
    "take_screenshot",
    "visualize",
]
