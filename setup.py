"""Package discovery for setuptools (the rest of the metadata is in pyproject.toml).

Every package under ``lerobot_pnp/`` ships, found rather than listed, plus the MJCF scene: it lives in ``envs/``
in the source tree and ships as the ``lerobot_pnp.assets`` package (``package-dir`` in pyproject.toml), a
mapping that pyproject's ``packages.find`` cannot express.
"""

from setuptools import find_packages, setup

setup(packages=[*find_packages(include=["lerobot_pnp", "lerobot_pnp.*"]), "lerobot_pnp.assets"])
