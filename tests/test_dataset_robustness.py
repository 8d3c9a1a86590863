"""Nothing lost, nothing silent (the dataset side), through the `lerobot-pnp` console script.

Each case asserts the data kept (or the dataset completed) and a one-line error with no traceback. The script runs
in a process of its own forked from a warm interpreter (tests/zygote.py); the absurd size runs the installed
executable itself.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import zygote

from lerobot_pnp.dataset import GenerateConfig, data_hash, generate, validate_dataset, verify_dataset
from lerobot_pnp.errors import DatasetError

PNP = str(Path(sys.executable).parent / "lerobot-pnp")
REPO = "test/pnp_rt"


def _env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("HF_")}
    env.update(OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1", HF_HUB_OFFLINE="1")
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1]) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _args(root: Path, n: int, *extra: str) -> list[str]:
    return [PNP, "generate", f"--repo_id={REPO}", f"--root={root}", f"--num_episodes={n}", "--progress=false", *extra]


def _run(args: list[str], timeout: float = 240) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, text=True, env=_env(), timeout=timeout, cwd="/")


def _one_line_error(res: subprocess.CompletedProcess, *needles: str) -> str:
    """Failed, with exactly one line on stderr naming the problem, and no traceback."""
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2, (res.returncode, res.stdout)  # the CLI's exit status for any PnPError
    assert "Traceback" not in res.stderr and len(lines) == 1, res.stderr[-3000:]
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def _wait_for(predicate, proc: subprocess.Popen, timeout: float = 120) -> None:
    deadline = time.time() + timeout
    while not predicate():
        assert proc.poll() is None, proc.communicate()
        assert time.time() < deadline, "timed out"
        time.sleep(0.05)


def _first_shard_done(root: Path):
    return lambda: (root / ".pnp_work" / "shards" / "shard-00000").is_dir()


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    root = tmp_path_factory.mktemp("rt") / "small"
    generate(GenerateConfig(repo_id=REPO, root=str(root), num_episodes=3, tasks=1, workers=1, progress=False))
    return root


# ---------------------------------------------------------------------------------------------- 1: overwrite
def test_overwrite_and_resume_refuse_a_running_generation(tmp_path, capsys):
    """The running generation is the console script; the two attempts go through ``cli.main`` in this process
    (the lock is the other process's either way)."""
    from lerobot_pnp.cli import main

    root = tmp_path / "running"
    proc = zygote.start(_args(root, 12, "--tasks=4", "--workers=1"))
    try:
        _wait_for(_first_shard_done(root), proc)
        os.kill(proc.pid, signal.SIGSTOP)  # a generation that is still running (paused, so the test is not a race)
        before = sorted(p.name for p in (root / ".pnp_work" / "shards").iterdir())
        for flag in ("--overwrite", "--resume"):
            rc = main(_args(root, 12, flag)[1:])
            err = capsys.readouterr().err
            _one_line_error(
                subprocess.CompletedProcess([flag], rc, "", err), "another `lerobot-pnp generate` is writing"
            )
        assert sorted(p.name for p in (root / ".pnp_work" / "shards").iterdir()) == before  # nothing deleted
        os.kill(proc.pid, signal.SIGCONT)
        assert proc.wait(timeout=240) == 0, proc.communicate()[1]
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGCONT)
            proc.kill()
    assert verify_dataset(root)["total_episodes"] == 12  # the running generation finished, nothing lost


# ---------------------------------------------------------------------------------------------- 2, 3: kill + resume
def test_resume_after_kill_keeps_unrelated_files_and_finishes(tmp_path, capsys):
    from lerobot_pnp.cli import main

    root = tmp_path / "killed"
    root.mkdir()
    proc = zygote.start(_args(root, 8, "--tasks=4", "--workers=1"))
    _wait_for(_first_shard_done(root), proc)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate()
    # The kill may land between a shard's rename and datatrove's completion record: drop every record so that
    # the resume must recognise the whole shards on their own (and adopt them rather than simulate them again).
    shutil.rmtree(root / ".pnp_work" / "logs" / "completions", ignore_errors=True)
    (root / "notes.txt").write_text("keep me")
    (root / "meta").mkdir(exist_ok=True)  # a partial commit of a killed merge is redone, not kept
    assert main(_args(root, 8, "--resume", "--workers=1")[1:]) == 0  # killed: the console script; resumed: cli.main
    assert json.loads(capsys.readouterr().out)["episodes_reused"] >= 2
    assert (root / "notes.txt").read_text() == "keep me"
    assert verify_dataset(root)["total_episodes"] == 8
    # --overwrite replaces the dataset, not the user's files
    generate(GenerateConfig(repo_id=REPO, root=str(root), num_episodes=2, workers=1, overwrite=True, progress=False))
    assert (root / "notes.txt").read_text() == "keep me" and validate_dataset(root)["total_episodes"] == 2


def test_resume_waits_for_a_committed_run_to_let_go_of_the_lock(small, monkeypatch):
    """A SLURM merge job removes the work folder (the sign a run is done) a moment before its process lets go
    of the lock: the --resume that follows waits for it; a holder that keeps the lock is refused."""
    import threading

    from lerobot_pnp.dataset import workdir
    from lerobot_pnp.outputs import FolderLock

    holder = FolderLock(small, "busy")  # the finishing merge job: the dataset committed, the lock still held
    threading.Timer(0.5, holder.close).start()
    again = generate(GenerateConfig(repo_id=REPO, root=str(small), num_episodes=3, resume=True, progress=False))
    assert again["status"] == "already complete" and holder.fd is None
    monkeypatch.setattr(workdir, "COMMIT_WAIT_S", 0.3)
    with FolderLock(small, "busy"), pytest.raises(DatasetError, match="another `lerobot-pnp generate` is writing"):
        generate(GenerateConfig(repo_id=REPO, root=str(small), num_episodes=3, resume=True, progress=False))


def test_ctrl_c_is_one_line_and_resume_finishes(tmp_path):
    root = tmp_path / "sigint"
    # SIGINT as in a terminal (a background job, ``cmd &`` or a CI runner, starts its children with it ignored)
    proc = zygote.start(_args(root, 8, "--tasks=4", "--workers=1"), new_session=True, sigint=True)
    _wait_for(_first_shard_done(root), proc)
    os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C in a terminal: the whole process group
    _, err = proc.communicate(timeout=120)
    _one_line_error(subprocess.CompletedProcess(proc.args, proc.returncode, "", err), "interrupted", "--resume")
    generate(GenerateConfig(repo_id=REPO, root=str(root), num_episodes=8, workers=1, resume=True, progress=False))
    assert verify_dataset(root)["total_episodes"] == 8


# ---------------------------------------------------------------------------------------------- 4: validation
def _rewrite_data(root: Path, edit) -> None:
    import pyarrow.parquet as pq

    path = sorted((root / "data").rglob("*.parquet"))[0]
    table = pq.read_table(path)
    pq.write_table(edit(table), path)


def test_validation_rejects_nan_shapes_and_removed_rows(small, tmp_path):
    import pyarrow as pa

    # NaN: named by episode and frame, through the CLI (--resume validates the dataset on disk)
    nan = tmp_path / "nan"
    shutil.copytree(small, nan)

    def poison(table):
        state = table.column("observation.state").to_pylist()
        state[13][2] = float("nan")  # episode 1, frame 3
        i = table.column_names.index("observation.state")
        return table.set_column(i, "observation.state", pa.array(state, type=table.schema.field(i).type))

    _rewrite_data(nan, poison)
    res = zygote.run(_args(nan, 3, "--resume"))
    _one_line_error(res, "observation.state holds non-finite values", "episode 1, frame 3")

    # info.json feature shape that disagrees with the data
    shape = tmp_path / "shape"
    shutil.copytree(small, shape)
    info = json.loads((shape / "meta" / "info.json").read_text())
    info["features"]["action"]["shape"] = [9]
    (shape / "meta" / "info.json").write_text(json.dumps(info))
    with pytest.raises(DatasetError, match=r"info.json says action has shape \[9\]"):
        validate_dataset(shape)

    # an episode's rows removed behind a consistent total_frames
    rows = tmp_path / "rows"
    shutil.copytree(small, rows)
    keep = np.ones(30, bool)
    keep[15] = False  # episode 1, frame 5
    _rewrite_data(rows, lambda t: t.filter(pa.array(keep)))
    info = json.loads((rows / "meta" / "info.json").read_text())
    info["total_frames"] -= 1
    (rows / "meta" / "info.json").write_text(json.dumps(info))
    with pytest.raises(DatasetError, match="episode 1 has 9 data rows but its metadata says 10"):
        validate_dataset(rows)
    assert data_hash(small)  # the original is untouched and readable
    validate_dataset(small)


# ---------------------------------------------------------------------------------------------- 6, 10: bad input
def test_absurd_sizes_are_one_line_from_the_console_script(tmp_path, capsys):
    """A size that would fill the disk, through the installed console script; a zero rate through its entry point."""
    from lerobot_pnp.cli import main

    root = tmp_path / "bad"
    res = _run([PNP, "generate", f"--root={root}", "--num_episodes=20000000"], timeout=120)
    _one_line_error(res, "--allow_huge")
    assert res.returncode == 2 and not root.exists()  # rejected before anything was written
    assert main(["generate", f"--root={root}", "--env.fps=0"]) == 2
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "env.fps" in lines[0] and not root.exists(), lines


@pytest.mark.parametrize(
    ("flags", "needle"),
    [
        (["--env.fps=20"], "keyframe control"),
        (["--seed=99999999999999999999"], "seed"),
        (["--executor=ray"], "executor"),
        (["--tasks=5", "--num_episodes=2"], "tasks"),
        (["--env.control_mode=video"], "env.control_mode"),
        (["--env.object_low=[0.9,0.2]"], "env.object_low"),
        (["--slurm.cpus_per_task=0"], "slurm.cpus_per_task"),
    ],
)
def test_bad_flags_are_one_line(tmp_path, flags, needle, capsys):
    from lerobot_pnp.cli import main

    root = tmp_path / "bad"
    assert main(["generate", f"--root={root}", *flags]) == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in err, err
    assert not root.exists()


def test_disk_full_is_one_line_and_resume_finishes(tmp_path):
    root = tmp_path / "full"

    # a file-size limit stands in for a full disk (Python ignores SIGXFSZ: writes get EFBIG)
    res = zygote.run(_args(root, 6, "--tasks=2", "--workers=1"), max_file_size=40 * 1024)
    line = _one_line_error(res, "cannot write the dataset", "--resume")
    assert str(root) in line
    generate(GenerateConfig(repo_id=REPO, root=str(root), num_episodes=6, workers=1, resume=True, progress=False))
    assert verify_dataset(root)["total_episodes"] == 6


def test_read_only_root_is_one_line(tmp_path):
    mnt = tmp_path / "ro"
    mnt.mkdir()
    ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(mnt)], capture_output=True)
    if ok.returncode != 0:
        pytest.skip(f"cannot mount a read-only tmpfs here: {ok.stderr.decode().strip()}")
    try:
        res = zygote.run(_args(mnt / "ds", 2))
        _one_line_error(res, "read-only", "--resume")
    finally:
        subprocess.run(["umount", str(mnt)], check=False)
