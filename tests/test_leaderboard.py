"""The leaderboard page is generated from committed eval_info.json outputs: the committed page is what they give."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lerobot_pnp import cli
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.leaderboard import LeaderboardConfig, analyse_rows, compact_table, render
from lerobot_pnp.evaluation.stock_suites import suite_names

ROOT = Path(__file__).resolve().parents[1]
RUNS, PAGE = ROOT / "docs" / "results" / "leaderboard", ROOT / "docs" / "leaderboard.md"


def test_the_committed_page_matches_the_committed_runs():
    if not RUNS.is_dir():
        pytest.skip("no committed leaderboard runs")
    assert PAGE.read_text() == render(LeaderboardConfig().runs_dir)
    assert cli.main(["leaderboard", "--check=true"]) == 0


def _write_row(root: Path, name: str, ok: int, n: int = 10) -> None:
    folder = root / name
    folder.mkdir(parents=True)
    outcomes = {s: [i < ok for i in range(n)] for s in suite_names("heldout")}
    per_task = [{"task_group": s, "task_id": 0, "metrics": {"successes": v}} for s, v in outcomes.items()]
    per_group = {s: {"n_episodes": n} for s in outcomes}
    (folder / "eval_info.json").write_text(json.dumps({"per_task": per_task, "per_group": per_group}))
    (folder / "row.json").write_text(json.dumps({"label": f"method {name}", "command": f"lerobot-eval ... {name}"}))


def test_rows_verdicts_and_the_command_to_add_one(tmp_path):
    _write_row(tmp_path / "runs", "a_good", ok=10)
    _write_row(tmp_path / "runs", "b_weak", ok=3)
    out = tmp_path / "leaderboard.md"
    args = ["leaderboard", f"--runs_dir={tmp_path / 'runs'}", f"--output={out}", "--episodes=10"]
    assert cli.main([*args, "--check=true"]) == 2 and not out.exists()  # no page yet
    assert cli.main(args) == 0 and cli.main([*args, "--check=true"]) == 0
    page = out.read_text()
    assert "| `a_good` | method a_good | - | 100.0% [72.2, 100.0] | 100.0 -> 100.0: generalises |" in page
    assert "| `b_weak` | method b_weak | - | 30.0% [10.8, 60.3] | 30.0 -> 30.0: no_recovery |" in page
    assert "--env.task heldout --eval.n_episodes 10" in page and "lerobot-pnp leaderboard --runs_dir" in page
    assert page.count("| heldout_") == 11 and "- `b_weak`: `lerobot-eval ... b_weak`" in page


def test_a_row_that_does_not_pair_writes_nothing(tmp_path):
    _write_row(tmp_path / "runs", "a", ok=10)
    _write_row(tmp_path / "runs", "b", ok=3, n=12)
    with pytest.raises(ConfigError, match="do not pair"):
        render(tmp_path / "runs", episodes=10)
    out = tmp_path / "leaderboard.md"
    assert cli.main(["leaderboard", f"--runs_dir={tmp_path / 'runs'}", f"--output={out}", "--episodes=10"]) == 2
    assert not out.exists()
    _write_row(tmp_path / "short", "c", ok=3)
    with pytest.raises(ConfigError, match="every suite needs 100 episodes"):
        render(tmp_path / "short")


def test_a_row_may_carry_a_short_name_and_its_budget_and_nothing_else(tmp_path):
    _write_row(tmp_path / "runs", "a", ok=10)
    meta_file = tmp_path / "runs" / "a" / "row.json"
    meta = json.loads(meta_file.read_text())
    meta_file.write_text(json.dumps({**meta, "name": "A", "budget": "10 demos, no training"}))
    assert "| `a` | method a | 10 demos, no training | 100.0% [72.2, 100.0] |" in render(tmp_path / "runs", episodes=10)
    rows, result, axes = analyse_rows(tmp_path / "runs", episodes=10)
    assert rows[0] == ("a", {**meta, "name": "A", "budget": "10 demos, no training"})
    assert str(result["table"]["nominal"]["a"].rate) == "100.0% [72.2, 100.0]" and axes[("timing", "a")].verdict
    _write_row(tmp_path / "runs", "b_floor", ok=0)
    table, left_out = compact_table(tmp_path / "runs", episodes=10, leave_out=("b_floor",))
    assert left_out == ["b_floor"] and "b_floor" not in table  # no short name: the row's folder stands in
    assert table.splitlines()[2].replace("\N{NO-BREAK SPACE}", " ") == (
        "| A | 10 demos, no training | 100 [72.2, 100] | 100 ✓ | 100 ✓ | 100 ✓ | 100 ✓ | 100 ✓ |"
    )
    meta_file.write_text(json.dumps({**meta, "budgets": "typo"}))
    with pytest.raises(ConfigError, match="unknown key 'budgets'; valid: .*'budget'"):
        render(tmp_path / "runs", episodes=10)
    meta_file.write_text(json.dumps({**meta, "budget": 300}))
    with pytest.raises(ConfigError, match="'budget' must be text, not 300"):
        render(tmp_path / "runs", episodes=10)
