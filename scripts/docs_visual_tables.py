"""The visual axes' blocks of docs/benchmark/heldout.md: each visual factor's training range
(``presets.VISUAL_TRAINING``) and held-out range (``sim/visual_suites.HELD_OUT_RANGES``) in readable units, read
from the code, and what the variation costs a camera episode, read from ``docs/results/bench_visual.json``
(``scripts/docs_tables.py`` renders them).
"""

from __future__ import annotations

import math


def _span(unit: str, scale: float = 1.0, digits: int = 0):
    """A range (lo, hi) of deviations as text in ``unit`` (each end times ``scale``)."""

    def text(r) -> str:
        lo, hi = (f"{scale * v:.{digits}f}" for v in r)
        return f"{lo} {unit}" if lo == hi else f"{lo} .. {hi} {unit}"

    return text


def _factor(r) -> str:
    """An intensity range of log2 deviations as the factors it scales the lights by (dimmer or brighter)."""
    lo, hi = r
    if lo == 0:
        return f"x {2**-hi:.2f} .. x {2**hi:.2f}"
    return f"x {2**-hi:.2f} .. x {2**-lo:.2f} or x {2**lo:.2f} .. x {2**hi:.2f}"


# field -> (what varies, how its range reads)
_READ = {
    "light_intensity_range": ("lights' intensity", _factor),
    "light_direction_range": ("lights turned about the table", _span("deg", math.degrees(1))),
    "light_color_range": ("lights' tint toward a random hue", _span("%", 100)),
    "cube_hue_range": ("cube's hue turned", _span("deg", 360)),
    "target_hue_range": ("place marker's hue turned", _span("deg", 360)),
    "table_hue_range": ("table top's hue turned", _span("deg", 360)),
    "camera_shift_range": ("front and overhead cameras moved", _span("cm", 100, 1)),
    "camera_tilt_range": ("front and overhead cameras turned", _span("deg", math.degrees(1), 1)),
    "wrist_camera_shift_range": ("wrist camera's mount moved", _span("mm", 1000)),
    "wrist_camera_tilt_range": ("wrist camera's mount turned", _span("deg", math.degrees(1), 1)),
    "distractors_range": ("distractors on the table", _span("")),
    "image_noise_range": ("image noise std", _span("% of full scale", 100)),
    "image_blur_range": ("image blur std", _span("px", 1, 1)),
}


def visual_ranges(base: str) -> str:
    """Per visual factor: its field, what varies, the training range, the held-out range and its suite."""
    from lerobot_pnp.presets import VISUAL_TRAINING
    from lerobot_pnp.sim.suites import SUITES
    from lerobot_pnp.sim.visual_suites import HELD_OUT_RANGES, VISUAL_AXES

    suite_of = {f: s for a in VISUAL_AXES for s in a.held_out for f, v in SUITES[s].parts[0].items()
                if v != VISUAL_TRAINING[f]}  # fmt: skip
    axis_of = {s: a.name for a in VISUAL_AXES for s in a.held_out}
    lines = ["| axis | field | what varies | training | held out | suite |", "|---|---|---|---|---|---|"]
    for field, (what, read) in _READ.items():
        train, held = VISUAL_TRAINING[field], HELD_OUT_RANGES[field]
        cells = [read(r).strip() for r in (train, held)]
        suite = suite_of[field]
        lines.append(f"| {axis_of[suite]} | `{field}` | {what} | {cells[0]} | {cells[1]} | `{suite}` |")
    return "\n".join(lines)


def visual_cost(base: str) -> str:
    """Per image size of ``docs/results/bench_visual.json``: nominal's camera episode, and per visual suite its cost
    over nominal's on the same seeds and the variation's own share of an episode."""
    import json
    from pathlib import Path

    record = json.loads((Path(__file__).resolve().parents[1] / "docs" / "results" / "bench_visual.json").read_text())
    sizes = record["sizes"]
    machine = record["machine"]
    lines = [
        f"Measured by `{record['command']}` on {machine['cpu']} ({machine['cores_available']} cores, shared; load "
        f"{record['load_before']} before), commit `{str(machine['commit'])[:7]}`, {machine['date']}: CPU time per "
        "episode, front and wrist cameras, target 1.20.",
        "",
        "| suite | " + " | ".join(f"{size}: x nominal | {size}: variation's share" for size in sizes) + " |",
        "|---|" + "---|---|" * len(sizes),
    ]
    nominal = " | ".join(f"{v['nominal']['episode_ms']:.0f} ms | -" for v in sizes.values())
    lines.append(f"| `nominal` (ms per episode) | {nominal} |")
    for name in next(iter(sizes.values())):
        if name != "nominal":
            cells = " | ".join(f"{v[name]['vs_nominal']:.2f} | {100 * v[name]['variation_share']:.0f} %"
                               for v in sizes.values())  # fmt: skip
            lines.append(f"| `{name}` | {cells} |")
    return "\n".join(lines)


BLOCKS = {"visual-ranges": visual_ranges, "visual-cost": visual_cost}
