"""What ``lerobot-eval`` spends before its first episode, and this plugin's share of it, side by side.

Each round runs two fresh processes in turn (their order alternating by round), the same Python and LeRobot:

- ``with``: ``lerobot-eval --env.type=baxter_pnp --policy.path=<pnp_lstm checkpoint>``, stopped when LeRobot's
  ``rollout`` is first called (the first episode's reset);
- ``without``: LeRobot's discovery blind to this plugin's distribution and a stock config (``--env.type=pusht
  --policy.type=act``), stopped when ``make_env`` is called: what every ``lerobot-eval`` pays before it builds
  an env, with none of this plugin.

Each process stamps the phases it passes: LeRobot's imports (up to ``lerobot_eval`` imported), plugin discovery
(``register_third_party_plugins``), config parsing (the first ``draccus.parse``, which reads the docstrings of every field of
the chosen configs for their help text), ``make_env``, and the policy with its processors up to the first episode
(``with`` only).
No module of this plugin is imported before discovery, so a difference in the imports phase is noise; the
differences of discovery and parsing are what the plugin adds to a stock ``lerobot-eval``, and the env and the
policy are this plugin's own. The median over rounds is written to ``--out``.

    OMP_NUM_THREADS=1 MUJOCO_GL=egl HF_HUB_OFFLINE=1 python benchmarks/bench_eval_startup.py [--rounds 5] \\
        [--checkpoint PATH] [--out docs/results/eval_startup.json]

Without ``--checkpoint`` it uses an untrained tiny pnp_lstm recording the ``full`` task
(``bench_stock_suites.tiny_checkpoint``): the start-up does not depend on the weights.
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_stock_suites import tiny_checkpoint

DISTRIBUTION = "lerobot_policy_pnp_lstm"
PHASES = ("imports", "discovery", "parse", "make_env", "make_policy", "total")

# argv: mode ("with" / "without"), then lerobot-eval's arguments. Prints one JSON line of time stamps
# (time.time(), comparable with the parent's launch stamp) and exits at the first episode (``with``) or at
# make_env (``without``).
_LAUNCHER = r"""
import importlib.metadata as md, json, sys, time
mode, args = sys.argv[1], sys.argv[2:]
if mode == "without":
    _all = md.distributions
    md.distributions = lambda *a, **k: (d for d in _all(*a, **k) if d.metadata.get("Name") != DISTRIBUTION)
stamps = {}
import lerobot.scripts.lerobot_eval as ev
import lerobot.configs.parser as parser
stamps["imports"] = time.time()

class Stop(Exception):
    pass

def after(name, fn, stop=False):
    def wrapped(*a, **k):
        if stop:
            stamps.setdefault(name, time.time())
            raise Stop
        out = fn(*a, **k)
        stamps.setdefault(name, time.time())  # the first call's end (a checkpoint's config is parsed again later)
        return out
    return wrapped

ev.register_third_party_plugins = after("discovery", ev.register_third_party_plugins)
parser.draccus.parse = after("parse", parser.draccus.parse)
ev.make_env = after("make_env", ev.make_env, stop=(mode == "without"))
ev.rollout = after("first_episode", ev.rollout, stop=True)
sys.argv = ["lerobot-eval", *args]
try:
    ev.main()
except Stop:
    pass
print(json.dumps({"stamps": stamps, "imported": DISTRIBUTION in sys.modules}))
""".replace("DISTRIBUTION", repr(DISTRIBUTION))


def run_once(mode: str, args: list[str]) -> dict[str, float]:
    """One fresh process: the seconds of each phase (``PHASES``), from launch."""
    launched = time.time()
    proc = subprocess.run(
        [sys.executable, "-c", _LAUNCHER, mode, *args],
        capture_output=True,
        text=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    if proc.returncode != 0:
        sys.exit(f"the {mode} run failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    record = json.loads(proc.stdout.strip().splitlines()[-1])
    if record["imported"] != (mode == "with"):
        sys.exit(f"the {mode} run {'did not import' if mode == 'with' else 'imported'} the plugin")
    stamps, out, previous = record["stamps"], {}, launched
    end = stamps["first_episode" if mode == "with" else "make_env"]
    for phase in ("imports", "discovery", "parse"):
        out[phase] = stamps[phase] - previous
        previous = stamps[phase]
    if mode == "with":
        out["make_env"] = stamps["make_env"] - previous
        out["make_policy"] = end - stamps["make_env"]  # the policy, its processors and the env processors
    out["total"] = end - launched
    return out


def cpu_model() -> str:
    """The processor's model name (Linux), else the platform's."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        return next(line.split(":", 1)[1].strip() for line in lines if line.startswith("model name"))
    except (OSError, StopIteration):
        import platform

        return platform.processor() or platform.machine()


def median_phases(runs: list[dict[str, float]]) -> dict[str, float]:
    return {p: statistics.median([r[p] for r in runs]) for p in PHASES if all(p in r for r in runs)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--checkpoint", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=Path("docs/results/eval_startup.json"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        ckpt = args.checkpoint or tiny_checkpoint(Path(tmp) / "pretrained_model")
        common = ["--eval.n_episodes=1", "--eval.batch_size=1", "--eval.use_async_envs=false", "--policy.device=cpu"]
        modes = {
            "with": [f"--policy.path={ckpt}", "--env.type=baxter_pnp", f"--output_dir={tmp}/with", *common],
            "without": ["--policy.type=act", "--env.type=pusht", f"--output_dir={tmp}/without", *common],
        }
        runs: dict[str, list[dict[str, float]]] = {m: [] for m in modes}
        for i in range(args.rounds):
            for mode in ("with", "without") if i % 2 == 0 else ("without", "with"):  # in turn, neither always first
                runs[mode].append(run_once(mode, modes[mode]))
            print(f"round {i + 1}/{args.rounds}: with {runs['with'][-1]['total']:.2f} s to the first episode, "
                  f"without {runs['without'][-1]['total']:.2f} s to make_env", flush=True)  # fmt: skip
    med = {m: median_phases(r) for m, r in runs.items()}
    added = {p: med["with"][p] - med["without"][p] for p in ("discovery", "parse")}
    own = med["with"]["make_env"] + med["with"]["make_policy"]
    result = {"cpu": cpu_model(), "cores": len(os.sched_getaffinity(0)), "load_average": os.getloadavg()[0], "rounds": args.rounds, "median_s": med, "plugin_adds_to_stock_s": added, "env_and_policy_s": own,
              "plugin_share_of_first_episode": (sum(added.values()) + own) / med["with"]["total"]}  # fmt: skip
    print(f"{'phase':<12}{'with':>9}{'without':>9}")
    for p in PHASES:
        print(f"{p:<12}{med['with'].get(p, float('nan')):>9.2f}{med['without'].get(p, float('nan')):>9.2f}")
    print(f"the plugin's share of the time to the first episode: {result['plugin_share_of_first_episode']:.0%}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
