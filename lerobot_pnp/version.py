"""The package's version (``lerobot_pnp.__version__``): a leaf, so a module that records the version imports it
from here and not the package, whose ``__init__`` registers the gymnasium env."""

__version__ = "0.1.0"
