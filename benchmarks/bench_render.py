"""What the cameras cost, with MuJoCo's visual effects and without them, measured side by side in one run.

    .venv/bin/python benchmarks/bench_render.py [--camera front] [--size 64] [--frames 40] [--num_episodes 6]
                                                [--png-dir DIR] [--out docs/results/bench_render.json]

1. One frame: ``BaxterPhysics.render`` of one camera at one size in the states of a few seeded `full` resets, with
   ``render_effects`` on (MuJoCo's defaults: shadows, reflections, 4x multisampling) and off, interleaved in
   rounds so that a shared machine's load falls on both alike; the median ms per frame of each.
2. Generation: ``lerobot-pnp generate`` of the same seeded `full` keyframe demonstrations with that camera
   recorded, effects on and off, and without cameras for reference, one worker each, wall time from outside
   (imports included); episodes per second.

``--png-dir`` saves each state's frame both ways (to look at what the policy would see). The load average before
each run is recorded: the machine may be shared, compare the two columns of one run only.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MUJOCO_GL", "egl")

PNP = str(Path(sys.executable).parent / "lerobot-pnp")
SETTINGS = {"effects": True, "no effects": False}


def frame_cost(camera: str, size: int, frames: int, png_dir: Path | None) -> dict:
    """Median ms per frame of each setting over ``frames`` renders, in rounds over 4 seeded states."""
    from lerobot_pnp.sim.env_config import make_env

    env = make_env(preset="full", render_mode=None)
    physics = env.unwrapped.physics
    times: dict[str, list[float]] = {name: [] for name in SETTINGS}
    for seed in range(4):
        env.reset(seed=seed)
        for name, effects in SETTINGS.items():
            image = physics.render(camera, size, size, effects)  # warm: the renderer is made on first use
            if png_dir is not None:
                from PIL import Image

                png_dir.mkdir(parents=True, exist_ok=True)
                Image.fromarray(image).save(png_dir / f"{camera}{size}_seed{seed}_{name.replace(' ', '_')}.png")
        for _ in range(frames // 4):
            for name, effects in SETTINGS.items():
                t0 = time.perf_counter()
                physics.render(camera, size, size, effects)
                times[name].append(1e3 * (time.perf_counter() - t0))
    env.close()
    return {name: round(statistics.median(t), 2) for name, t in times.items()}


def generation_cost(camera: str | None, size: int, effects: bool, episodes: int) -> dict:
    """``lerobot-pnp generate`` of ``episodes`` `full` demonstrations, one worker, timed from outside."""
    with tempfile.TemporaryDirectory(prefix="bench_render_") as tmp:
        args = [PNP, "generate", "--repo_id=bench/render", f"--root={tmp}/ds", f"--num_episodes={episodes}"]
        args += ["--seed=0", "--workers=1", "--progress=false", "--env.preset=full"]
        if camera is not None:
            args += [f"--env.cameras=[{camera}]", f"--env.image_height={size}", f"--env.image_width={size}"]
            args += [f"--env.render_effects={str(effects).lower()}"]
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        res = subprocess.run(args, capture_output=True, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
        wall = time.perf_counter() - t0
    if res.returncode != 0:
        raise SystemExit(f"generate failed:\n{res.stderr[-3000:]}")
    summary = json.loads(res.stdout)
    return {"load_before": round(load, 2), "wall_s": round(wall, 2), "episodes_per_s": round(episodes / wall, 3),
            "simulate_cpu_s": summary.get("simulate_cpu_s"), "write_cpu_s": summary.get("write_cpu_s")}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--camera", default="front")
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--num_episodes", type=int, default=6)
    parser.add_argument("--png-dir", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    frame = frame_cost(args.camera, args.size, args.frames, args.png_dir)
    print(f"one {args.camera} frame at {args.size}x{args.size}: " + ", ".join(f"{k} {v} ms" for k, v in frame.items()))
    gen = {name: generation_cost(args.camera, args.size, fx, args.num_episodes) for name, fx in SETTINGS.items()}
    gen["no cameras"] = generation_cost(None, args.size, False, args.num_episodes)
    for name, row in gen.items():
        print(f"generate {args.num_episodes} full episodes, {name}: {row['wall_s']} s ({row['episodes_per_s']} ep/s; "
              f"simulating {row['simulate_cpu_s']} s CPU; load before {row['load_before']})")  # fmt: skip
    result = {
        "command": " ".join(["benchmarks/bench_render.py", *sys.argv[1:]]),
        "camera": args.camera,
        "size": args.size,
        "cpu_count": os.cpu_count(),
        "frame_ms": frame,
        "generation": {"episodes": args.num_episodes, "preset": "full", "workers": 1, **gen},
    }
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
