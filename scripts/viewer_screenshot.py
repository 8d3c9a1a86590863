"""Render the README's picture: the real Rerun viewer (headless) on one dataset episode -> docs/viewer.png.

    python scripts/viewer_screenshot.py --root outputs/datasets/baxter_pnp_keyframe --episode 12
    python scripts/viewer_screenshot.py --root outputs/datasets/baxter_pnp_keyframe --recovery
    python scripts/viewer_screenshot.py            # no dataset given: one expert episode is generated first
    python scripts/viewer_screenshot.py --policy <pretrained_model> --seed 100000 \
        --env-changes '{"drop_prob": 1.0, "keyframe_budget": 20}'   # a policy rollout (here: a re-pick)

The picture is what ``lerobot-pnp viz --screenshot`` writes (the viewer laid out by the recording's
blueprint), scaled down (and palette-quantised if large) so the README stays light. ``--recovery`` picks the
first episode in which the expert recovered (its FSM phase goes back, e.g. a re-grasp after a missed grasp).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

MAX_BYTES = 400_000


def first_recovery(repo_id: str, root: str) -> int:
    """Index of the first episode whose ``phase.index`` decreases somewhere (the expert went back)."""
    import numpy as np

    from lerobot_pnp.errors import DatasetError
    from lerobot_pnp.viz.sources import open_dataset

    table = open_dataset(repo_id, root).hf_dataset.with_format("numpy")
    episodes, phases = np.asarray(table["episode_index"]).ravel(), np.asarray(table["phase.index"]).ravel()
    back = np.flatnonzero((np.diff(phases) < 0) & (np.diff(episodes) == 0))
    if len(back) == 0:
        raise DatasetError(f"no recovery episode in {root}: no episode's phase.index ever decreases")
    return int(episodes[back[0]])


def main() -> int:
    from PIL import Image

    from lerobot_pnp.errors import PnPError
    from lerobot_pnp.viz import VizConfig, visualize

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", help="dataset folder (default: generate one expert episode in a temp folder)")
    parser.add_argument("--repo-id", default="local/baxter_pnp_keyframe")
    parser.add_argument("--episode", type=int, default=0)
    parser.add_argument("--recovery", action="store_true", help="show the first episode whose phase goes back")
    parser.add_argument("--seed", type=int, default=0, help="seed of the generated episode (without --root)")
    parser.add_argument("--policy", help="a checkpoint (pretrained_model folder): show its rollout from --seed")
    parser.add_argument("--env-changes", default="{}", help="task fields for the rollout, JSON (with --policy)")
    parser.add_argument("--out", default=str(REPO / "docs" / "viewer.png"))
    parser.add_argument("--window", default="1600x1000", help="viewer size in logical points")
    parser.add_argument("--width", type=int, default=1600, help="width of the saved picture (px)")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="viewer_shot_") as tmp:
        root = args.root
        try:
            if args.policy:
                shot = Path(tmp) / "shot.png"
                summary = visualize(
                    VizConfig(
                        policy_path=args.policy,
                        env_changes=json.loads(args.env_changes),
                        seed=args.seed,
                        screenshot=str(shot),
                        window_size=args.window,
                    )
                )
                root = args.policy
            elif root is None:
                from lerobot_pnp.dataset import GenerateConfig, generate

                root = str(Path(tmp) / "dataset")
                generate(
                    GenerateConfig(
                        repo_id=args.repo_id, root=root, num_episodes=1, seed=args.seed, workers=1, progress=False
                    )
                )
            if not args.policy:
                episode = first_recovery(args.repo_id, root) if args.recovery else args.episode
                shot = Path(tmp) / "shot.png"
                cfg = VizConfig(
                    repo_id=args.repo_id,
                    root=root,
                    episode_index=episode,
                    screenshot=str(shot),
                    window_size=args.window,
                )
                summary = visualize(cfg)
        except PnPError as err:
            print(f"viewer_screenshot: {err}", file=sys.stderr)
            return 2
        img = Image.open(shot).convert("RGB")
        if img.width > args.width:
            img = img.resize((args.width, round(img.height * args.width / img.width)), Image.LANCZOS)
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        img.save(out, optimize=True)
        if out.stat().st_size > MAX_BYTES:  # a palette keeps the README light; octree keeps the small colours
            img.quantize(colors=256, method=Image.Quantize.FASTOCTREE).save(out, optimize=True)
    run = summary["runs"][0]
    print(
        f"wrote {out} ({out.stat().st_size // 1000} kB): {run['run']} of {root}, {run.get('frames', run.get('steps', '?'))} frames"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
