"""Render the visual axes at a glance: each visual suite's training and held-out extremes -> docs/assets/visual_axes.png.

    python scripts/visual_axes_screenshots.py [--seed 2] [--size 128x96] [--out docs/assets/visual_axes.png]

One row per held-out visual suite (``sim.visual_suites``), after a first row of the scene as modelled; four
columns: the front camera at the factor's training extreme and at its held-out extreme, then the wrist camera
likewise. An extreme is the factor's range collapsed to its upper end (``(hi, hi)``) with every other visual factor
off, so a row shows that factor alone; each frame is the env's observation at the reset of ``--seed`` (the policy's
view: its render settings, and the image noise and blur where the row's factor is one of those).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("OMP_NUM_THREADS", "1")
REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

LABEL_WIDTH = 120  # pixels of the row labels
HEADER = 18  # pixels of the column titles
COLUMNS = ("front, training", "front, held out", "wrist, training", "wrist, held out")


def _frames(changes: dict, seed: int, height: int, width: int) -> dict:
    from lerobot_pnp.sim.env_config import make_env

    env = make_env(preset="full", cameras=["front", "wrist"], image_height=height, image_width=width, **changes)
    obs, _ = env.reset(seed=seed)
    env.close()
    return obs["pixels"]


def rows(seed: int, height: int, width: int) -> list[tuple[str, list]]:
    """(label, the row's four frames) per row: the scene as modelled, then each held-out visual suite."""
    from lerobot_pnp.presets import VISUAL_TRAINING
    from lerobot_pnp.sim.suites import SUITES
    from lerobot_pnp.sim.visual_suites import VISUAL_AXES

    nominal = _frames({}, seed, height, width)
    out = [("as modelled", [nominal["front"], nominal["front"], nominal["wrist"], nominal["wrist"]])]
    for name in (n for axis in VISUAL_AXES for n in axis.held_out):
        (part,) = SUITES[name].parts
        fields = [f for f, v in part.items() if v != VISUAL_TRAINING[f]]
        train = _frames({f: (VISUAL_TRAINING[f][1],) * 2 for f in fields}, seed, height, width)
        held = _frames({f: (part[f][1],) * 2 for f in fields}, seed, height, width)
        out.append((name.removeprefix("heldout_"), [train["front"], held["front"], train["wrist"], held["wrist"]]))
    return out


def grid(table: list[tuple[str, list]], height: int, width: int):
    """The rows as one picture: labels on the left, column titles on top."""
    from PIL import Image, ImageDraw

    image = Image.new("RGB", (LABEL_WIDTH + 4 * width, HEADER + len(table) * height), "white")
    draw = ImageDraw.Draw(image)
    for c, title in enumerate(COLUMNS):
        draw.text((LABEL_WIDTH + c * width + 4, 3), title, fill="black")
    for r, (label, frames) in enumerate(table):
        y = HEADER + r * height
        draw.text((4, y + height // 2 - 6), label.replace("_", " "), fill="black")
        for c, frame in enumerate(frames):
            image.paste(Image.fromarray(frame), (LABEL_WIDTH + c * width, y))
    return image


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=2, help="the reset shown in every frame")
    parser.add_argument("--size", default="128x96", help="WIDTHxHEIGHT of each frame")
    parser.add_argument("--out", default=str(REPO / "docs" / "assets" / "visual_axes.png"))
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))
    image = grid(rows(args.seed, height, width), height, width)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    image.save(tmp, format="PNG", optimize=True)
    tmp.replace(out)
    print(f"wrote {out} ({out.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
