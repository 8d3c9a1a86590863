"""What installing the plugin costs a LeRobot command that never touches this env, side by side.

LeRobot imports every distribution named ``lerobot_policy_*`` in every ``lerobot-*`` process
(``register_third_party_plugins``), so this plugin's import is paid by a real-robot ``lerobot-calibrate`` too.
This runs the same Python, the same LeRobot and the same command twice per round, in fresh processes and in
turn (with, without, with, without ...): "without" is the same launcher with ``importlib.metadata.distributions``
filtered so that LeRobot's discovery does not see the ``lerobot_policy_pnp_lstm`` distribution (nothing else
differs; a probe run checks that the plugin is imported in one mode and not in the other). Each run's wall time
is read around the child, its peak memory (max RSS) from the operating system's accounting of that child
(``os.wait4``). Target: median difference <= 0.3 s and <= 50 MB. The probe also times
``register_third_party_plugins()`` itself in both modes.

    OMP_NUM_THREADS=1 HF_HUB_OFFLINE=1 python benchmarks/bench_plugin_import.py [--rounds 7] \\
        [--command lerobot-calibrate --help] [--out docs/results/plugin_import.json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

DISTRIBUTION = "lerobot_policy_pnp_lstm"
TARGET_SECONDS, TARGET_MB = 0.3, 50.0

# argv: mode ("with" / "without"), then the lerobot command and its arguments; "probe" as the command times
# LeRobot's plugin discovery alone and prints whether the plugin was imported.
_LAUNCHER = r"""
import importlib, importlib.metadata as md, json, resource, sys, time
mode, command, args = sys.argv[1], sys.argv[2], sys.argv[3:]
if mode == "without":
    _all = md.distributions
    md.distributions = lambda *a, **k: (d for d in _all(*a, **k) if d.metadata.get("Name") != DISTRIBUTION)
if command == "probe":
    sys.argv = ["lerobot-calibrate"]
    importlib.import_module("lerobot.scripts.lerobot_calibrate")
    from lerobot.utils.import_utils import register_third_party_plugins
    t = time.perf_counter()
    register_third_party_plugins()
    seconds = time.perf_counter() - t
    print(json.dumps({"imported": DISTRIBUTION in sys.modules, "discovery_s": seconds,
                      "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
    sys.exit(0)
sys.argv = [command, *args]
module = importlib.import_module("lerobot.scripts." + command.replace("-", "_"))
sys.exit(module.main())
""".replace("DISTRIBUTION", repr(DISTRIBUTION))


def run_once(mode: str, command: list[str]) -> dict:
    """One fresh process: its wall seconds, its peak RSS (MB) and its exit status."""
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-c", _LAUNCHER, mode, *command], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL
    )
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    return {"wall_s": wall, "max_rss_mb": usage.ru_maxrss / 1024, "rc": proc.returncode, "stdout": out.decode()}


def probe(mode: str) -> dict:
    result = run_once(mode, ["probe"])
    return json.loads(result["stdout"].strip().splitlines()[-1])


def summary(values: list[float]) -> dict:
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--out", type=Path, default=Path("docs/results/plugin_import.json"))
    parser.add_argument("--command", nargs=argparse.REMAINDER, default=["lerobot-calibrate", "--help"])
    args = parser.parse_args()

    probes = {mode: probe(mode) for mode in ("with", "without")}
    if not probes["with"]["imported"] or probes["without"]["imported"]:
        raise SystemExit(f"the plugin is not imported only in the 'with' mode: {probes}")
    run_once("with", args.command), run_once("without", args.command)  # warm the file cache, not counted
    runs: dict[str, list[dict]] = {"with": [], "without": []}
    for _ in range(args.rounds):
        for mode in ("with", "without"):
            runs[mode].append(run_once(mode, args.command))
    if any(r["rc"] != 0 for rs in runs.values() for r in rs):
        raise SystemExit(f"a run failed: {[(m, r['rc']) for m, rs in runs.items() for r in rs]}")
    stats = {m: {k: summary([r[k] for r in rs]) for k in ("wall_s", "max_rss_mb")} for m, rs in runs.items()}
    diff_s = stats["with"]["wall_s"]["median"] - stats["without"]["wall_s"]["median"]
    diff_mb = stats["with"]["max_rss_mb"]["median"] - stats["without"]["max_rss_mb"]["median"]
    result = {
        "command": args.command,
        "rounds": args.rounds,
        "python": sys.version.split()[0],
        "cpus": os.cpu_count(),
        "runs": stats,
        "median_difference": {"wall_s": diff_s, "max_rss_mb": diff_mb},
        "target": {"wall_s": TARGET_SECONDS, "max_rss_mb": TARGET_MB},
        "within_target": diff_s <= TARGET_SECONDS and diff_mb <= TARGET_MB,
        "discovery_probe": probes,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"{' '.join(args.command)}: {args.rounds} rounds, with / without the plugin, median (min-max)")
    for mode in ("with", "without"):
        w, m = stats[mode]["wall_s"], stats[mode]["max_rss_mb"]
        print(
            f"  {mode:8s} {w['median']:.2f} s ({w['min']:.2f}-{w['max']:.2f})  "
            f"{m['median']:.0f} MB ({m['min']:.0f}-{m['max']:.0f})  "
            f"discovery {probes[mode]['discovery_s']:.3f} s"
        )
    print(f"  difference {diff_s:+.2f} s, {diff_mb:+.0f} MB (target <= {TARGET_SECONDS} s, <= {TARGET_MB:.0f} MB)")
    print(f"  written to {args.out}")
    return 0 if result["within_target"] else 1


if __name__ == "__main__":
    sys.exit(main())
