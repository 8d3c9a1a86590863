"""The suite catalogue's blocks (docs/benchmark/suites.md, docs/benchmark/heldout.md), generated from the code.

``scripts/docs_tables.py`` owns the pages' generated blocks; this module holds the blocks that read the suite
catalogue (``sim/suites.py``) and the visual axes' ranges (``presets.VISUAL_TRAINING``,
``sim/visual_suites.HELD_OUT_RANGES``).
"""

from __future__ import annotations

import math


def changes_text(changes: dict, base: dict) -> str:
    """The fields of ``changes`` whose value differs from ``base``'s, as `field=value` code, or "none"."""

    def fmt(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        if isinstance(v, (tuple, list)):
            return "(" + ", ".join(fmt(x) for x in v) + ")"
        return str(v)

    shown = {k: v for k, v in changes.items() if k not in base or fmt(base[k]) != fmt(v)}
    return ", ".join(f"`{k}={fmt(v)}`" for k, v in shown.items()) or "none"


def suite_catalogue(base: str) -> str:
    """Every suite of ``sim/suites.py``, grouped as the studies use them, with what it changes."""
    from lerobot_pnp.presets import FULL_TASK, PAPER_TASK, VISUAL_TRAINING
    from lerobot_pnp.sim.suites import ALL_AXES, SUITES
    from lerobot_pnp.sim.visual_suites import VISUAL_SUITES

    groups = {
        "The paper-task study (base: the task a policy was trained on)": [],
        "The held-out protocol (base: the `full` task)": [],
        "DAgger's suites (`quiet*`: every perturbation off, then one at a time)": [],
        "The visual axes (`train_visual`: changes from the `paper` task; the others: from `train_visual`)": [],
    }
    titles = list(groups)
    for s in SUITES.values():
        key = 3 if s.name in VISUAL_SUITES else 1 if s.name.startswith(("train_", "heldout_")) else 2 if (
            s.name.startswith("quiet")) else 0  # fmt: skip
        groups[titles[key]].append(s)
    out = [
        f"{len(SUITES)} suites. Changes shown: every field a paper-task suite sets; for the held-out protocol's and "
        "DAgger's suites, the fields whose value differs from the `full` preset (their base); for the visual "
        "suites, as their group says."
    ]
    for i, (title, suites) in enumerate(groups.items()):
        out += ["", f"### {title}", "", "| suite | what it is | env-config changes |", "|---|---|---|"]
        for s in suites:
            ref = {} if i == 0 else FULL_TASK if i < 3 else PAPER_TASK if s.name == "train_visual" else (
                {**FULL_TASK, **VISUAL_TRAINING})  # fmt: skip
            changes = "; ".join(changes_text(p, ref) for p in s.parts)
            out.append(f"| `{s.name}` | {s.description} | {changes} |")
    out += ["", "### Held-out axes", "", "| axis | what varies | in distribution | held out |", "|---|---|---|---|"]
    for a in ALL_AXES:
        ins, held = (", ".join(f"`{n}`" for n in names) for names in (a.in_distribution, a.held_out))
        out.append(f"| {a.name} | {a.description} | {ins} | {held} |")
    return "\n".join(out)


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


BLOCKS = {"suite-catalogue": suite_catalogue, "visual-ranges": visual_ranges}
