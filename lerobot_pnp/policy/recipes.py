"""The recovering planner's recipe: the ``pnp_lstm`` settings it is trained with (``RECOVERING_RECIPE``; ``configs/dagger.json`` names them too; what
each part is and why: docs/policy.md). DAgger (``lerobot_pnp.dagger``) and the study (``lerobot_pnp.report``)
train it on their own data."""

from __future__ import annotations

from typing import Any

RECOVERING_RECIPE: dict[str, Any] = {
    "mode": "recovering",
    "hidden_size": 256,
    "num_layers": 2,  # a second layer carries two steps of latency (docs/policy.md)
    "optimizer_lr": 3e-3,
    "lr_scheduler": "cosine",
    "scheduler_warmup_steps": 200,
    "latency_augment_prob": 0.5,
    "latency_augment_jitter": 0.5,
    "latency_augment_stretch": True,
    "binary_gripper": True,
    "await_observation": True,
    "still_arm_phases": [7],  # the place's open keeps the arm (Phase.PLACE_DESCEND) ...
    "still_arm_tol": 0.05,  # ... where the network would move it by more than a refinement
    "memory_per_attempt": True,  # a re-pick starts from the zero state (docs/policy.md)
}
