"""``python -m lerobot_pnp.train_fast``: the same as ``lerobot-pnp train``."""

import sys

from lerobot_pnp.cli import main

sys.exit(main(["train", *sys.argv[1:]]))
