"""Run every benchmark of the project in one command and print a summary table.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/run_all.py [--size small|default] [--only bench_sim ...]
                                                             [--out outputs/bench_all]

Each ``benchmarks/bench_*.py`` runs as its own process (so one crashing does not stop the rest) with small
settings by default (``--size small``: a few minutes in all on 2 cores) or its own defaults (``--size
default``: the numbers quoted in the README, much longer). A benchmark found here without known small
settings runs with its defaults. Its full output goes to ``<out>/<name>.log``; the table shows the exit
status, the wall time and the last lines it printed (each benchmark ends with its own summary).
``bench_policy`` needs a keyframe dataset: the demo's (``outputs/demo/dataset``) when it exists, else a
small one is generated first (``lerobot-pnp generate``, 200 episodes).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def small_args(name: str, out: Path, dataset: Path) -> list[str] | None:
    """Small settings per benchmark (read from each one's argparse); None = not known here."""
    return {
        "bench_sim": ["--n_episodes", "10"],
        "bench_expert": ["--n_episodes", "50", "--out", str(out / "bench_expert.json")],
        "bench_dataset": [
            "--num_episodes", "60", "--dense-episodes", "4", "--profile-episodes", "10", "--out", str(out / "bench_dataset"),
        ],
        "bench_policy": [
            "--quick", "--dataset_root", str(dataset), "--workdir", str(out / "bench_policy_work"),
            "--out", str(out / "bench_policy.json"),
        ],
        "bench_training": [
            "--epochs", "2", "--workdir", str(out / "bench_training"), "--out", str(out / "bench_training.json"),
        ],
        "bench_visual": ["--rounds", "2", "--sizes", "64x64"],
        "bench_planner": [
            "--config", "configs/dagger_small.json", "--sections", "dagger,latency",
            "--output_dir", str(out / "bench_planner"),
        ],
    }.get(name)  # fmt: skip


def default_args(name: str, out: Path, dataset: Path) -> list[str]:
    return ["--dataset_root", str(dataset)] if name == "bench_policy" else []


def ensure_dataset(out: Path) -> Path:
    from lerobot_pnp.dataset.layout import is_dataset

    demo = ROOT / "outputs" / "demo" / "dataset"
    if is_dataset(demo):
        return demo
    root = out / "dataset"
    if not is_dataset(root):
        cli = Path(sys.executable).with_name("lerobot-pnp")
        cmd = [str(cli), "generate", "--root", str(root), "--num_episodes", "200", "--progress", "false"]
        cmd += ["--resume"] if root.exists() else []
        print("generating a small dataset for bench_policy:", " ".join(cmd), flush=True)
        subprocess.run(cmd, check=True, cwd=ROOT)
    return root


def tail(text: str, n: int) -> list[str]:
    lines = [ln.rstrip() for ln in text.splitlines() if ln.strip() and "it/s]" not in ln and "s/it]" not in ln]
    return lines[-n:]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--size", choices=("small", "default"), default="small")
    p.add_argument("--only", nargs="*", default=None, help="benchmark names (default: every benchmarks/bench_*.py)")
    p.add_argument("--out", type=Path, default=ROOT / "outputs" / "bench_all")
    p.add_argument("--lines", type=int, default=4, help="lines of each benchmark's own summary to show")
    p.add_argument("--width", type=int, default=150, help="cut table lines to this many characters")
    args = p.parse_args()
    found = sorted(f.stem for f in HERE.glob("bench_*.py"))
    names = args.only or found
    unknown = sorted(set(names) - set(found))
    if unknown:
        p.error(f"unknown benchmark(s) {unknown}; found: {found}")
    args.out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    dataset = ensure_dataset(args.out) if "bench_policy" in names else args.out / "dataset"
    rows = []
    for name in names:
        extra = small_args(name, args.out, dataset) if args.size == "small" else None
        settings = "small" if extra is not None else "defaults"
        extra = extra if extra is not None else default_args(name, args.out, dataset)
        cmd = [sys.executable, str(HERE / f"{name}.py"), *extra]
        print(f"\n=== {name} ({settings}): {' '.join(cmd[1:])}", flush=True)
        start = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - start
        log = args.out / f"{name}.log"
        log.write_text(proc.stdout + "\n--- stderr ---\n" + proc.stderr)
        summary = tail(proc.stdout, args.lines) if proc.returncode == 0 else tail(proc.stderr, 2)
        print("\n".join(summary), flush=True)
        rows.append((name, settings, proc.returncode, wall, summary, log))
    print("\n" + "=" * 100)
    print(
        f"{'benchmark':<15} {'settings':<9} {'status':<8} {'wall s':>7}  summary (last lines; full log in {args.out})"
    )
    print("-" * 100)
    for name, settings, rc, wall, summary, _ in rows:
        status = "ok" if rc == 0 else f"FAIL {rc}"
        first, *rest = summary or ["(no output)"]
        print(f"{name:<15} {settings:<9} {status:<8} {wall:7.0f}  {first}"[: args.width])
        for line in rest:
            print(f"{'':<42}{line}"[: args.width])
    return 0 if all(r[2] == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
