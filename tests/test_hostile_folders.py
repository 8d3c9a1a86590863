"""Every command that writes, in a hostile output folder: the user's files survive, whatever the folder holds.

One row per command of ``lerobot-pnp``: how to run it (tiny settings) and the top-level names it writes in its
output folder. Each case plants something in the folder and runs the command; afterwards every file that was
there before (and every input) has its checksum, and a refusal is one line with a non-zero exit:

- a user's own file or folder under each of the command's output names: refused, untouched;
- a symbolic link out of the folder under an output name: refused, the link's target untouched;
- a folder the command may not write: refused in one line, nothing written;
- a second instance on the same folder: refused in one line, nothing written;
- the command killed (SIGKILL) mid-run beside a user's file: the file survives, and the next run either
  finishes or refuses in one line;
- a plain run beside a user's file: it finishes and the file survives.

A command added to ``cli.COMMANDS`` without a row (or a reason it writes nothing) fails the first test.
"""

from __future__ import annotations

import hashlib
import os
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest
import zygote
from clis import exe

from lerobot_pnp import cli
from lerobot_pnp.outputs import FolderLock

ROOT = Path(__file__).resolve().parents[1]
REPORT_FLAGS = [
    "--preset", "quick", "--methods", '["lookup_table"]', "--num_episodes", "10", "--workers", "1",
    "--suites", '[{"name": "nominal", "n_episodes": 2}]', "--train_seeds", "[1000]", "--cli_check_episodes", "0",
]  # fmt: skip


@dataclass(frozen=True)
class Row:
    argv: tuple[str, ...]  # the command line; {out} is the output folder, {D} the dataset, {E1}/{E2} eval runs
    names: tuple[str, ...]  # top-level names it writes into {out}

    def args(self, out: Path, inputs: dict[str, Path]) -> list[str]:
        values = {"{out}": str(out), **{"{" + k + "}": str(v) for k, v in inputs.items()}}
        args = []
        for arg in self.argv:
            for key, value in values.items():
                arg = arg.replace(key, value)
            args.append(arg)
        return args


ROWS: dict[str, Row] = {
    "generate": Row(("generate", "--root", "{out}", "--repo_id", "local/h", "--num_episodes", "2"), ("meta", "data")),
    "train": Row(
        ("train", "--dataset_root", "{D}", "--dataset_repo_id", "local/h", "--epochs", "1", "--output_dir", "{out}"),
        ("checkpoints", "loss_curve.png", "loss_curve.csv", "test_keyframe_error.json", "train_fast_config.json"),
    ),
    "lookup-table": Row(
        ("lookup-table", "--dataset_root", "{D}", "--output_dir", "{out}"), ("config.json", "model.safetensors")
    ),
    "dagger": Row(
        (
            "dagger",
            "--output_dir",
            "{out}",
            "--num_episodes",
            "4",
            "--rounds",
            "0",
            "--epochs",
            "1",
            "--n_episodes",
            "0",
        ),
        ("demos", "round_00", "summary.json"),
    ),
    "report": Row(("report", "--output_dir", "{out}", *REPORT_FLAGS), ("dataset", "evals", "report.md")),
    "demo": Row(("demo", "--output_dir", "{out}", *REPORT_FLAGS), ("dataset", "evals", "report.md")),
    "compare": Row(("compare", "{E1}", "{E2}", "--output_dir", "{out}"), ("compare.md", "compare.json", "compare.png")),
    "leaderboard": Row(
        ("leaderboard", "--runs_dir", "{ROWS}", "--output", "{out}/leaderboard.md"), ("leaderboard.md",)
    ),
    "viz": Row(("viz", "--root", "{D}", "--repo_id", "local/h", "--save", "{out}/rec.rrd"), ("rec.rrd",)),
    "expert": Row(("expert", "--n_episodes", "2", "--progress", "false", "--output_dir", "{out}"), ("eval_info.json",)),
}
NOT_WRITING = {"push": "uploads a dataset to the Hugging Face Hub; writes no local file"}


def _sums(*roots: Path) -> dict[str, str]:
    out = {}
    for root in roots:
        for p in sorted(root.rglob("*")):
            if p.is_file() and not p.is_symlink():
                out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def _kept(before: dict[str, str], after: dict[str, str]) -> list[str]:
    """The files of ``before`` that are gone or changed in ``after``."""
    return [name for name, digest in before.items() if after.get(name) != digest]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("inputs")
    made = {"D": base / "D", "E1": base / "E1", "E2": base / "E2", "ROWS": ROOT / "docs" / "results" / "leaderboard"}
    assert cli.main(["generate", "--root", str(made["D"]), "--repo_id", "local/h", "--num_episodes", "4"]) == 0
    for key in ("E1", "E2"):
        assert cli.main(["expert", "--n_episodes", "2", "--progress", "false", "--output_dir", str(made[key])]) == 0
    return made


def _run(row: str, out: Path, inputs, capsys) -> tuple[int, str]:
    capsys.readouterr()
    rc = cli.main(ROWS[row].args(out, inputs))
    return rc, capsys.readouterr().err.strip()


def _refused(rc: int, err: str, *names: str) -> None:
    assert rc == 2, err
    last = err.splitlines()[-1] if err else ""
    assert last and len(last) < 600, err
    assert any(n in last for n in names), f"the refusal does not name {names}: {last}"


def test_every_command_has_a_row_or_writes_nothing():
    assert set(cli.COMMANDS) == set(ROWS) | set(NOT_WRITING), "a command without a hostile-folder row"


@pytest.mark.parametrize(("row", "name"), [(r, n) for r, row in ROWS.items() for n in row.names])
def test_a_users_entry_under_an_output_name_is_refused_untouched(tmp_path, inputs, capsys, row, name):
    out = tmp_path / "out"
    out.mkdir()
    planted = out / name
    if "." in name:
        planted.write_text("the user's own file")
    else:
        planted.mkdir()
        (planted / "mine.txt").write_text("the user's own file")
    before = _sums(tmp_path, *inputs.values())
    rc, err = _run(row, out, inputs, capsys)
    _refused(rc, err, name)
    assert _kept(before, _sums(tmp_path, *inputs.values())) == []


@pytest.mark.parametrize("row", ROWS)
def test_a_link_out_of_the_folder_is_never_followed(tmp_path, inputs, capsys, row):
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.mkdir()
    (victim / "keep.txt").write_text("elsewhere")
    name = ROWS[row].names[0]
    (out / name).symlink_to(victim if "." not in name else victim / "keep.txt")
    before = _sums(victim, *inputs.values())
    rc, err = _run(row, out, inputs, capsys)
    _refused(rc, err, name)
    assert _kept(before, _sums(victim, *inputs.values())) == []
    assert (out / name).is_symlink()


@pytest.mark.parametrize("row", ROWS)
def test_a_folder_it_may_not_write_is_refused_in_one_line(tmp_path, inputs, capsys, monkeypatch, row):
    out = tmp_path / "out"
    out.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if Path(p) == out else real(p, mode, **kw))
    rc, err = _run(row, out, inputs, capsys)
    _refused(rc, err, str(out))
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("row", ROWS)
def test_a_second_instance_on_the_same_folder_is_refused(tmp_path, inputs, capsys, row):
    out = tmp_path / "out"
    out.mkdir()
    with FolderLock(out, busy="held by the test"):
        rc, err = _run(row, out, inputs, capsys)
    _refused(rc, err, "another")
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("row", ROWS)
def test_killed_mid_run_then_run_again_beside_a_users_file(tmp_path, inputs, capsys, row):
    out = tmp_path / "out"
    out.mkdir()
    (out / "NOTES.txt").write_text("the user's notes")
    before = _sums(tmp_path, *inputs.values())
    proc = zygote.start([exe("lerobot-pnp"), *ROWS[row].args(out, inputs)])  # a process of its own, killed below
    deadline = time.monotonic() + 120
    while proc.poll() is None and time.monotonic() < deadline:
        if any(p.name != "NOTES.txt" for p in out.iterdir()):
            break
        time.sleep(0.02)
    if proc.poll() is None:
        proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert _kept(before, _sums(tmp_path, *inputs.values())) == []
    rc, err = _run(row, out, inputs, capsys)
    assert rc == 0 or (rc == 2 and len(err.splitlines()) == 1), err
    assert _kept(before, _sums(tmp_path, *inputs.values())) == []


@pytest.mark.parametrize("row", ROWS)
def test_a_run_beside_a_users_file_finishes_and_keeps_it(tmp_path, inputs, capsys, row):
    out = tmp_path / "out"
    out.mkdir()
    (out / "NOTES.txt").write_text("the user's notes")
    before = _sums(tmp_path, *inputs.values())
    rc, err = _run(row, out, inputs, capsys)
    assert rc == 0, err
    assert _kept(before, _sums(tmp_path, *inputs.values())) == []
    assert all((out / name).exists() for name in ROWS[row].names), sorted(p.name for p in out.iterdir())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))
