"""What the expert's labels of one DAgger run teach, per round and rollout suite.

``python benchmarks/dagger_labels.py OUTPUT_DIR [--json FILE]`` reads the rollout datasets of a
``lerobot-pnp dagger`` run and prints, per round and suite: episodes, labelled frames, frames whose label
was not the executed action ("disagree", from ``rollouts.json``) or not the policy's own action
("policy_disagree"; the same with ``beta = 0``), and the frames of a *recovery*: those from
the first return of the label's phase to an earlier phase on. A recovery frame is "first" when its label is
still the phase the recovery restarted at (its first keyframe), "later" when the labels have moved past it
(the 2nd, 3rd, ... keyframes of the recovery, which a rollout only reaches when its executor followed the
first); "depth" is the mean over recoveries of how many phases past the restart its labels got. Rollout episode ``i`` ran suite ``rollout_suites[i % len(rollout_suites)]`` (the loop's rule).
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np


def recovery_counts(phases: np.ndarray) -> dict:
    """Recovery frames of one episode's label phases: first-keyframe and later-keyframe label counts, and the
    depth (how many phases past its restart the labels of the recovery got: 9 or so for a whole recovery)."""
    back = np.flatnonzero(np.diff(phases) < 0)
    if not len(back):
        return {"recoveries": 0, "first": 0, "later": 0, "depth": 0}
    start = int(back[0]) + 1
    rec = phases[start:]
    first, later = int((rec <= rec[0]).sum()), int((rec > rec[0]).sum())
    return {"recoveries": 1, "first": first, "later": later, "depth": int(rec.max() - rec[0])}


def round_stats(out: Path, rnd: int, suites: list[str]) -> dict:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = out / f"round_{rnd:02d}" / "rollouts"
    ds = LeRobotDataset("local/x", root=root)
    frames = ds.hf_dataset.with_format("numpy")[:]
    ep_index, phase = frames["episode_index"].reshape(-1), frames["phase.index"].reshape(-1)
    stats: dict = defaultdict(lambda: defaultdict(int))
    for e in np.unique(ep_index):
        s = stats[suites[int(e) % len(suites)]]
        p = phase[ep_index == e]
        s["episodes"] += 1
        s["frames"] += len(p)
        for k, v in recovery_counts(p).items():
            s[k] += v
    record = json.loads((out / f"round_{rnd:02d}" / "rollouts.json").read_text())
    for suite, counts in (record.get("by_suite") or {}).items():
        stats[suite]["disagree"] = counts["disagree"]
        stats[suite]["executed_labels"] = counts["executed_labels"]
        stats[suite]["policy_disagree"] = counts.get("policy_disagree", "-")
        stats[suite]["policy_successes"] = counts["policy_successes"]
    for s in stats.values():  # the sum of depths -> the mean depth per recovery
        s["depth"] = round(s["depth"] / s["recoveries"], 2) if s["recoveries"] else 0
    return {"beta": record.get("beta", 0.0), "suites": {k: dict(v) for k, v in stats.items()}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("output_dir", type=Path)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    cfg = json.loads((args.output_dir / "round_01" / "rollouts.json").read_text())["parts"]
    suites = cfg["suites"]
    rounds = sorted(int(p.name[6:]) for p in args.output_dir.glob("round_*") if (p / "rollouts.json").is_file())
    result = {rnd: round_stats(args.output_dir, rnd, suites) for rnd in rounds}
    cols = "episodes frames policy_successes executed_labels disagree policy_disagree recoveries first later depth"
    cols = cols.split()
    print("| round | beta | suite | " + " | ".join(cols) + " |\n" + "|---" * (len(cols) + 3) + "|")
    for rnd, r in result.items():
        for suite, s in r["suites"].items():
            print(f"| {rnd} | {r['beta']:g} | {suite} | " + " | ".join(str(s.get(c, "-")) for c in cols) + " |")
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
