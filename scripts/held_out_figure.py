"""Draw the held-out protocol's figure (``report.figures.draw_held_out``, which a study now draws itself) from a
study's ``summary.json``, for a study run before the figure existed.

    python scripts/held_out_figure.py docs/results/study/heldout/summary.json /tmp/held_out.png
"""

import json
import sys
from pathlib import Path

from lerobot_pnp.evaluation.stats import Rate
from lerobot_pnp.report.figures import draw_held_out, held_out_panels
from lerobot_pnp.report.methods import METHODS

summary_path, out = Path(sys.argv[1]), Path(sys.argv[2])
summary = json.loads(summary_path.read_text())
success = summary["success"]
panels = held_out_panels(list(success))


def _rate(cell: dict) -> Rate:
    return Rate(round(cell["rate"] * cell["n"]), cell["n"])


rates = {METHODS[m].label: {s: _rate(c[m]) for s, c in success.items() if m in c} for m in summary["config"]["methods"]}
prov = f"{summary['command']}  |  drawn from {summary_path} by scripts/held_out_figure.py"
draw_held_out(panels, rates, out, prov)
print(out)
