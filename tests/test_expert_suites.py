"""``lerobot-pnp expert --env.task <suites>``: the suites of stock ``lerobot-eval`` (names, per-suite env configs,
seeds), the study's outcomes episode by episode, and an ``eval_info.json`` that ``compare`` reads like
``lerobot-eval``'s."""

from __future__ import annotations

import json

from lerobot_pnp import cli
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

SUITES = ("nominal", "drop")
SEED, N = 300, 3


def test_expert_on_suites_writes_stock_eval_info_equal_to_the_study(tmp_path, capsys):
    from lerobot_pnp.evaluation.compare import parse_runs
    from lerobot_pnp.report.builders import expert_eval
    from lerobot_pnp.sim.suites import SUITES as CATALOGUE

    out = tmp_path / "expert"
    args = ["--env.preset", "paper", "--env.task", ",".join(SUITES), "--n_episodes", str(N), "--seed", str(SEED)]
    assert cli.main(["expert", *args, "--progress", "false", "--output_dir", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    info = json.loads((out / "eval_info.json").read_text())
    assert [t["task_group"] for t in info["per_task"]] == list(SUITES) == list(summary["suites"])
    assert all(t["task_id"] == 0 and t["metrics"]["seeds"] == list(range(SEED, SEED + N)) for t in info["per_task"])

    base = BaxterPnPEnvConfig(preset="paper")
    study = {
        s: [r.success for r in expert_eval(None, None, CATALOGUE[s].env_configs(base)[0], N, SEED, 1)] for s in SUITES
    }
    ours = {t["task_group"]: t["metrics"]["successes"] for t in info["per_task"]}
    assert ours == study and any(ours["nominal"]), (ours, study)
    assert info["per_group"]["nominal"]["n_episodes"] == N and info["overall"]["n_episodes"] == N * len(SUITES)
    assert info["overall"]["pc_success"] == 100 * sum(map(sum, ours.values())) / (N * len(SUITES))
    (run,) = parse_runs([f"expert={out}"])  # compare (and the leaderboard) read it as a lerobot-eval output
    assert run.suites[0] == {s: {0: ours[s]} for s in SUITES}


def test_expert_refuses_an_unknown_suite_in_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "expert"
    args = ["expert", "--env.task", "nominal,nosuch", "--n_episodes", "1", "--output_dir", str(out)]
    assert cli.main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown suite 'nosuch'" in err and "heldout" in err and "\n" not in err, err
    assert not out.exists()


def test_expert_default_task_keeps_its_summary(tmp_path, capsys):
    """Without suites: one task, the causes summary as before, and eval_info.json under the env type's name."""
    from lerobot_pnp.evaluation.expert_eval import ExpertEvalConfig, evaluate_expert

    cfg = ExpertEvalConfig(n_episodes=2, seed=SEED, progress=False, output_dir=str(tmp_path))
    summary = evaluate_expert(cfg)
    assert {"success_rate", "failures_by_cause", "recoveries", "episodes_per_s"} <= set(summary)
    info = json.loads((tmp_path / "eval_info.json").read_text())
    assert [t["task_group"] for t in info["per_task"]] == ["baxter_pnp"]
    assert info["per_group"]["baxter_pnp"]["pc_success"] == 100 * summary["success_rate"]
