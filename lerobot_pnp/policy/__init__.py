"""The ``pnp_lstm`` policy: LSTM task planner (de Magistris et al. 2016) as a LeRobot 0.6.1 plugin.

Importing this package registers the ``pnp_lstm`` policy type with LeRobot (the config class is
decorated with ``PreTrainedConfig.register_subclass``). LeRobot then finds ``PnpLstmPolicy`` and
``make_pnp_lstm_pre_post_processors`` by file-name convention from the config's module
(``configuration_pnp_lstm`` -> ``modeling_pnp_lstm`` / ``processor_pnp_lstm``).

This package knows tensors and LeRobot features only: it never imports the simulator or the expert.
"""

from .configuration_pnp_lstm import PnpLstmConfig
from .modeling_pnp_lstm import PnpLstmPolicy
from .processor_pnp_lstm import make_pnp_lstm_pre_post_processors

__all__ = ["PnpLstmConfig", "PnpLstmPolicy", "make_pnp_lstm_pre_post_processors"]
