"""The leaderboard page is generated from committed eval_info.json outputs: the committed page is what they give."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from lerobot_pnp import cli
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.evaluation.leaderboard import MARKER, LeaderboardConfig, analyse_rows, compact_table, render
from lerobot_pnp.sim.stock_suites import suite_names

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
    args = ["leaderboard", f"--runs_dir={tmp_path / 'runs'}", f"--output={out}", "--n_episodes=10"]
    assert cli.main([*args, "--check=true"]) == 2 and not out.exists()  # no page yet
    assert cli.main(args) == 0 and cli.main([*args, "--check=true"]) == 0
    page = out.read_text()
    # 10 episodes a suite cannot show 5 points: the rule says so, and its interval
    assert (
        "| `a_good` | method a_good | - | 100.0% [72.2, 100.0] | 100.0 -> 100.0: undecided (+0.0 [-16.1, +16.1]) |"
        in page
    )
    assert (
        "| `b_weak` | method b_weak | - | 30.0% [10.8, 60.3] | 30.0 -> 30.0: no verdict (+0.0 [-26.8, +26.8]) |" in page
    )
    assert "--env.task heldout --eval.n_episodes 10" in page and "lerobot-pnp leaderboard --runs_dir" in page
    assert page.count("| heldout_") == 11 and "- `b_weak`: `lerobot-eval ... b_weak`" in page


def test_a_row_that_does_not_pair_writes_nothing(tmp_path):
    _write_row(tmp_path / "runs", "a", ok=10)
    _write_row(tmp_path / "runs", "b", ok=3, n=12)
    with pytest.raises(ConfigError, match="do not pair"):
        render(tmp_path / "runs", n_episodes=10)
    out = tmp_path / "leaderboard.md"
    assert cli.main(["leaderboard", f"--runs_dir={tmp_path / 'runs'}", f"--output={out}", "--n_episodes=10"]) == 2
    assert not out.exists()
    _write_row(tmp_path / "short", "c", ok=3)
    with pytest.raises(ConfigError, match="every suite needs 100 episodes"):
        render(tmp_path / "short")


def test_a_row_may_carry_a_short_name_and_its_budget_and_nothing_else(tmp_path):
    _write_row(tmp_path / "runs", "a", ok=10)
    meta_file = tmp_path / "runs" / "a" / "row.json"
    meta = json.loads(meta_file.read_text())
    meta_file.write_text(json.dumps({**meta, "name": "A", "budget": "10 demos, no training"}))
    assert "| `a` | method a | 10 demos, no training | 100.0% [72.2, 100.0] |" in render(
        tmp_path / "runs", n_episodes=10
    )
    rows, result, axes = analyse_rows(tmp_path / "runs", n_episodes=10)
    assert rows[0] == ("a", {**meta, "name": "A", "budget": "10 demos, no training"})
    assert str(result["table"]["nominal"]["a"].rate) == "100.0% [72.2, 100.0]" and axes[("timing", "a")].verdict
    _write_row(tmp_path / "runs", "b_floor", ok=0)
    table, left_out = compact_table(tmp_path / "runs", n_episodes=10, leave_out=("b_floor",))
    assert left_out == ["b_floor"] and "b_floor" not in table  # no short name: the row's folder stands in
    assert table.splitlines()[2].replace("\N{NO-BREAK SPACE}", " ") == (
        "| A | 10 demos, no training | 100 [72.2, 100] | 100 ? | 100 ? | 100 ? | 100 ? | 100 ? |"
    )
    meta_file.write_text(json.dumps({**meta, "budgets": "typo"}))
    with pytest.raises(ConfigError, match="unknown key 'budgets'; valid: .*'budget'"):
        render(tmp_path / "runs", n_episodes=10)
    meta_file.write_text(json.dumps({**meta, "budget": 300}))
    with pytest.raises(ConfigError, match="'budget' must be text, not 300"):
        render(tmp_path / "runs", n_episodes=10)


def _args(root: Path, out: Path) -> list[str]:
    return ["leaderboard", f"--runs_dir={root / 'runs'}", f"--output={out}", "--n_episodes=10"]


def test_only_its_own_page_is_replaced(tmp_path, monkeypatch, capsys):
    """A file the command did not write is refused in one line and kept; its own page (the manifest's, or one
    carrying the marker line, as the committed page does) is replaced."""
    _write_row(tmp_path / "runs", "a", ok=10)
    mine = tmp_path / "docs" / "leaderboard.md"  # a project's own page, at the default --output
    mine.parent.mkdir()
    mine.write_text("# My project's leaderboard\n")
    monkeypatch.chdir(tmp_path)
    assert cli.main(["leaderboard", f"--runs_dir={tmp_path / 'runs'}", "--n_episodes=10"]) == 2
    err = capsys.readouterr().err.strip()
    assert "'docs/leaderboard.md' exists and is not a page `lerobot-pnp leaderboard` wrote" in err and "\n" not in err
    assert mine.read_text() == "# My project's leaderboard\n"

    page = tmp_path / "page.md"
    assert cli.main(_args(tmp_path, page)) == 0  # a new page: recorded in the folder's manifest
    assert page.read_text().splitlines()[0] == MARKER
    _write_row(tmp_path / "runs", "b", ok=3)
    assert cli.main(_args(tmp_path, page)) == 0 and "`b`" in page.read_text()
    (tmp_path / ".pnp_manifest.json").unlink()  # the marker alone proves it (the committed page has no manifest)
    shutil.rmtree(tmp_path / "runs" / "b")
    assert cli.main(_args(tmp_path, page)) == 0 and "`b`" not in page.read_text()


@pytest.mark.parametrize("target", ["runs/a/eval_info.json", "runs/a/row.json", "runs/s/seed1/eval_info.json"])
def test_an_output_that_is_one_of_its_inputs_is_refused(tmp_path, capsys, target):
    _write_row(tmp_path / "runs", "a", ok=10)
    _write_row(tmp_path / "runs" / "s", "seed1", ok=7)  # a row of one training seed in a sub-folder
    (tmp_path / "runs" / "s" / "seed1" / "row.json").rename(tmp_path / "runs" / "s" / "row.json")
    before = (tmp_path / target).read_bytes()
    assert cli.main(_args(tmp_path, tmp_path / target)) == 2
    assert "is one of the rows' own files" in capsys.readouterr().err
    assert (tmp_path / target).read_bytes() == before


def test_row_text_is_escaped_on_the_page(tmp_path):
    _write_row(tmp_path / "runs", "a", ok=10)
    meta = {"label": "<script>alert(1)</script> x|y\n| injected |", "budget": "a|b\nc", "name": "n|m",
            "command": "lerobot-eval ... | tail -n 1\n- injected item"}  # fmt: skip
    (tmp_path / "runs" / "a" / "row.json").write_text(json.dumps(meta))
    page = render(tmp_path / "runs", n_episodes=10)
    outside_code = re.sub(r"(`+).*?\1", "", page)
    assert "<script>" not in outside_code and "&lt;script&gt;alert(1)&lt;/script&gt; x\\|y \\| injected \\|" in page
    assert "| `a` | &lt;script&gt;" in page and "| a\\|b c |" in page and "\n- injected item" not in page
    assert "- `a`: `lerobot-eval ... | tail -n 1 - injected item`" in page
    for table in re.findall(r"(?:^\|.*\n)+", page, re.M):
        rows = table.splitlines()
        assert len({len(re.findall(r"(?<!\\)\|", r)) for r in rows}) == 1, table
    table, _ = compact_table(tmp_path / "runs", n_episodes=10)
    assert table.splitlines()[2].startswith("| n\\|m | a\\|b c |")


@pytest.mark.parametrize("content", [b"{not json", b'{"label": "\xff\xfe"}', b"[" * 100_000])
def test_a_malformed_row_json_is_one_line_naming_it(tmp_path, capsys, content):
    _write_row(tmp_path / "runs", "a", ok=10)
    (tmp_path / "runs" / "a" / "row.json").write_bytes(content)
    out = tmp_path / "page.md"
    assert cli.main(_args(tmp_path, out)) == 2
    err = capsys.readouterr().err.strip()
    assert f"{str(tmp_path / 'runs' / 'a' / 'row.json')!r} is not readable JSON" in err and "\n" not in err
    assert not out.exists()
