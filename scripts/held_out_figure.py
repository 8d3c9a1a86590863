"""Draw the held-out protocol's figure (``report.figures._held_out``, which a study now draws itself) from a
study's ``summary.json``, for a study run before the figure existed.

    python scripts/held_out_figure.py docs/results/heldout_summary.json docs/results/heldout_figures/held_out.png
"""

import json
import sys
from pathlib import Path

from lerobot_pnp.evaluation.stats import Rate
from lerobot_pnp.evaluation.suites import HELD_OUT_AXES
from lerobot_pnp.report import plots
from lerobot_pnp.report.methods import METHODS
from lerobot_pnp.report.results import TARGET

summary_path, out = Path(sys.argv[1]), Path(sys.argv[2])
summary = json.loads(summary_path.read_text())
success = summary["success"]
panels = [
    (a.name, [s for s in a.in_distribution if s in success], [s for s in a.held_out if s in success])
    for a in HELD_OUT_AXES
    if any(s in success for s in a.held_out)
]


def _rate(cell: dict) -> Rate:
    return Rate(round(cell["rate"] * cell["n"]), cell["n"])


rates = {METHODS[m].label: {s: _rate(c[m]) for s, c in success.items() if m in c} for m in summary["config"]["methods"]}
prov = f"{summary['command']}  |  drawn from {summary_path} by scripts/held_out_figure.py"
title = f"trained vs held-out conditions per disturbance axis (dashed: {100 * TARGET:.0f} %)"
plots.axis_panels(panels, rates, out, prov, title, target=TARGET)
print(out)
