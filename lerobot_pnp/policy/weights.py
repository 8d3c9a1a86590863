"""The check a loaded model's weights get from every loader: pnp_lstm's own ``from_pretrained`` (also under stock
``lerobot-eval``) and the strict loader of any policy (``evaluation.checkpoints.load_policy``). Imports nothing;
it lives in the policy package, which imports nothing of the simulator."""

from __future__ import annotations

from typing import Any


def non_finite_weights(state_dict: dict[str, Any]) -> list[str]:
    """The names of the floating-point tensors that hold NaN or inf, in ``state_dict`` order: a corrupt
    checkpoint, named when it is loaded rather than as a NaN action steps later."""
    return [name for name, t in state_dict.items() if t.is_floating_point() and not bool(t.isfinite().all())]
