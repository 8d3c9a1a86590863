"""The policies, as LeRobot 0.6.1 plugin types: ``pnp_lstm`` (the LSTM task planner of de Magistris et al. 2016),
``pnp_pixels`` (the same planner on camera images) and ``pnp_lookup_table`` (the nearest-demonstration replay).

Importing this package registers the ``pnp_lstm`` policy type with LeRobot (the config class is
decorated with ``PreTrainedConfig.register_subclass``). LeRobot then finds ``PnpLstmPolicy`` and
``make_pnp_lstm_pre_post_processors`` by file-name convention from the config's module
(``configuration_pnp_lstm`` -> ``modeling_pnp_lstm`` / ``processor_pnp_lstm``).

The planner (``ClockedPlanner``, the paper's, or ``RecoveringPlanner``; ``planner.Planner`` is their one
interface) is a plain ``nn.Module`` that ``PnpLstmPolicy`` wraps (LeRobot's ``ACT`` / ``ACTPolicy`` split);
the pre-processor's check step is the one place that checks observations. ``pnp_pixels``
(``configuration_pnp_pixels``) is the same planner on joint state + camera images, an image encoder in front.

This package knows tensors and LeRobot features only: it never imports the simulator or the expert (only
the package's error classes from ``lerobot_pnp.errors``).
"""

from .configuration_pnp_lstm import PnpLstmConfig
from .configuration_pnp_pixels import PnpPixelsConfig

# The modeling side (torch modules) loads on first use: LeRobot imports this package wherever it parses a policy
# config (its plugin discovery registers ``pnp_lstm``), and finds the policy by module name when it builds one.
_LAZY = {
    "ClockedPlanner": ".clocked",
    "PnpLstm": ".clocked",
    "PnpLstmPolicy": ".modeling_pnp_lstm",
    "PnpPixelsPolicy": ".modeling_pnp_pixels",
    "Planner": ".planner",
    "PlannerState": ".planner",
    "make_pnp_lstm_pre_post_processors": ".processor_pnp_lstm",
    "make_pnp_pixels_pre_post_processors": ".processor_pnp_pixels",
    "RecoveringPlanner": ".recovering",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "ClockedPlanner",
    "Planner",
    "PlannerState",
    "PnpLstm",
    "PnpLstmConfig",
    "PnpLstmPolicy",
    "PnpPixelsConfig",
    "PnpPixelsPolicy",
    "RecoveringPlanner",
    "make_pnp_lstm_pre_post_processors",
    "make_pnp_pixels_pre_post_processors",
]
