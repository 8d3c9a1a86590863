"""What `generate` may replace in its dataset root: only the entries it provably wrote there.

The root is an output folder (``lerobot_pnp.outputs``): the dataset entries and the work folder are claimed in
its manifest before they are written, a dataset older than manifests is proven by the marker files only
`generate` writes, the user's other files stay, and a symbolic link inside the root is never followed.
Tiny runs (1-3 episodes, 32x32 images), through ``cli.main`` where the message is what the user sees.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import pytest

from lerobot_pnp import cli
from lerobot_pnp.dataset import GenerateConfig, data_hash, generate, validate_dataset
from lerobot_pnp.errors import DatasetError
from lerobot_pnp.outputs import MANIFEST_FILE

REPO = "test/pnp_own"
COMMAND = "lerobot-pnp generate"
CAMERA = ["--env.control_mode=dense", "--env.cameras=[front]", "--env.image_height=32", "--env.image_width=32"]


def _args(root: Path, n: int, *extra: str) -> list[str]:
    return ["generate", f"--repo_id={REPO}", f"--root={root}", f"--num_episodes={n}", "--progress=false", *extra]


def _checksums(folder: Path) -> dict[str, str]:
    """Every file under ``folder``, links not followed (relative name -> sha256, or the link's target)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_symlink():
            out[str(p.relative_to(folder))] = "-> " + str(p.readlink())
        elif p.is_file():
            out[str(p.relative_to(folder))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def _one_line(capsys, rc: int, *needles: str, absent: tuple[str, ...] = ()) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in lines[0], lines[0]
    for needle in absent:
        assert needle not in lines[0], lines[0]
    return lines[0]


def _users_files(root: Path, outside: Path) -> None:
    """A user's own files in the dataset root: a note, a folder of theirs, a link out of the root."""
    root.mkdir(parents=True, exist_ok=True)
    (root / "notes.txt").write_text("keep me")
    (root / "plots").mkdir()
    (root / "plots" / "a.csv").write_text("1,2\n")
    outside.mkdir()
    (outside / "thesis.tex").write_text("mine")
    (root / "elsewhere").symlink_to(outside, target_is_directory=True)


def _owned(root: Path) -> set[str]:
    return set(json.loads((root / MANIFEST_FILE).read_text())["owners"][COMMAND])


# ------------------------------------------------------------------------------------- --overwrite, cameras
def test_overwrite_replaces_a_camera_dataset_and_keeps_the_users_files(tmp_path, capsys):
    """LeRobot leaves an ``images/`` folder in a camera dataset: the overwrite replaces it with the rest."""
    root, outside = tmp_path / "C", tmp_path / "outside"
    assert cli.main(_args(root, 1, *CAMERA)) == 0
    assert (root / "images").is_dir()
    _users_files(root, outside)
    users = {k: v for k, v in _checksums(root).items() if k.split("/")[0] in ("notes.txt", "plots", "elsewhere")}
    theirs = _checksums(outside)
    assert cli.main(_args(root, 1, *CAMERA, "--seed=5", "--overwrite=true")) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert validate_dataset(root)["total_episodes"] == 1
    assert json.loads((root / "meta" / "pnp_generate.json").read_text())["generation"]["seed"] == 5
    assert {k: v for k, v in _checksums(root).items() if k in users} == users  # the user's files, byte for byte
    assert _checksums(outside) == theirs  # and what their link points at
    assert not {"notes.txt", "plots", "elsewhere"} & _owned(root)
    assert {"meta", "data", "videos"} <= _owned(root)


def test_overwrite_keeps_the_old_dataset_until_the_new_one_is_committed(tmp_path, monkeypatch):
    """A replacement that fails leaves the previous dataset readable, and a camera dataset's replacement that
    was stopped during its commit finishes with --resume."""
    from lerobot_pnp.dataset import generation

    root = tmp_path / "C"
    env = {"control_mode": "dense", "cameras": ["front"], "image_height": 32, "image_width": 32}
    cfg = {"repo_id": REPO, "root": str(root), "num_episodes": 1, "workers": 1, "progress": False, "env": env}
    generate(GenerateConfig(**cfg))
    before, old_hash = _checksums(root), data_hash(root)

    def unreachable(step, tasks, workers, logs):
        raise DatasetError("shard 0: env: object box corner (3.000, 3.000) is out of the arm's reach")

    monkeypatch.setattr(generation, "run_local", unreachable)
    with pytest.raises(DatasetError, match="reach"):
        generate(GenerateConfig(**cfg, seed=9, overwrite=True))
    assert data_hash(root) == old_hash and validate_dataset(root)["total_episodes"] == 1
    assert {k: v for k, v in _checksums(root).items() if k != MANIFEST_FILE} == {
        k: v for k, v in before.items() if k != MANIFEST_FILE
    }
    monkeypatch.undo()

    real_replace, moved = os.replace, []

    def stop_after_two(src, dst):  # killed in the middle of the commit: two entries moved in, the rest not
        if Path(src).parent.name == "merged":
            if len(moved) == 2:
                raise KeyboardInterrupt
            moved.append(dst)
        real_replace(src, dst)

    for seed, manifest in ((9, True), (11, False)):  # without it: a root left so by a version before manifests
        moved.clear()
        monkeypatch.setattr(os, "replace", stop_after_two)
        with pytest.raises(DatasetError, match="--resume"):
            generate(GenerateConfig(**cfg, seed=seed, overwrite=True))
        monkeypatch.undo()
        if not manifest:
            (root / MANIFEST_FILE).unlink()
        summary = generate(GenerateConfig(**cfg, seed=seed, resume=True))
        assert summary["episodes"] == 1 and validate_dataset(root)["total_episodes"] == 1
        assert json.loads((root / "meta" / "pnp_generate.json").read_text())["generation"]["seed"] == seed


# ------------------------------------------------------------------------------------- links inside the root
def _stopped_before_merge(root: Path, monkeypatch) -> Path:
    """The work folder of a run of 2 episodes in 2 shards, stopped before its merge; returns it."""
    from lerobot_pnp.dataset import generation

    def stopped(*args):
        raise KeyboardInterrupt

    monkeypatch.setattr(generation, "merge_and_commit", stopped)
    with pytest.raises(DatasetError, match="interrupted"):
        generate(GenerateConfig(repo_id=REPO, root=str(root), num_episodes=2, tasks=2, workers=1, progress=False))
    monkeypatch.undo()
    return root / ".pnp_work"


def test_resume_never_follows_a_work_folder_link_out_of_the_root(tmp_path, capsys, monkeypatch):
    work = _stopped_before_merge(tmp_path / "other", monkeypatch)  # another generation's work folder
    before = _checksums(tmp_path / "other")
    root = tmp_path / "R"
    root.mkdir()
    (root / ".pnp_work").symlink_to(Path("..") / "other" / ".pnp_work", target_is_directory=True)
    capsys.readouterr()
    for flag in ("--resume=true", "--overwrite=true", "--tasks=2"):
        rc = cli.main(_args(root, 2, "--tasks=2", flag))
        _one_line(capsys, rc, str(root / ".pnp_work"), "symbolic link", "remove it", absent=("--resume",))
        assert (root / ".pnp_work").is_symlink() and _checksums(tmp_path / "other") == before

    # a link deeper inside a work folder of the root's own: refused too, the link's target untouched
    (work / "shards" / "shard-00001" / "pnp_shard.json").unlink()  # a shard a resume would redo
    before = _checksums(tmp_path / "other")
    inner = tmp_path / "R2"
    (inner / ".pnp_work").mkdir(parents=True)
    (inner / ".pnp_work" / "run.json").write_bytes((work / "run.json").read_bytes())
    (inner / ".pnp_work" / "shards").symlink_to(work / "shards", target_is_directory=True)
    rc = cli.main(_args(inner, 2, "--tasks=2", "--resume=true"))
    _one_line(capsys, rc, str(inner / ".pnp_work" / "shards"), "symbolic link", "--overwrite")
    assert _checksums(tmp_path / "other") == before
    assert cli.main(_args(inner, 2, "--tasks=2", "--overwrite=true")) == 0  # the advice: the link unlinked
    assert validate_dataset(inner)["total_episodes"] == 2 and _checksums(tmp_path / "other") == before


def test_a_work_folder_link_is_one_line_that_says_to_remove_it_not_to_resume(tmp_path, capsys):
    """A link the resume cannot delete: the advice must not be the --resume that fails the same way again."""
    root, target = tmp_path / "R", tmp_path / "target"
    target.mkdir()
    (target / "keep.txt").write_text("keep")
    root.mkdir()
    (root / ".pnp_work").symlink_to(target, target_is_directory=True)
    for _ in range(2):
        rc = cli.main(_args(root, 1, "--resume=true"))
        _one_line(capsys, rc, ".pnp_work", "symbolic link", "remove it", absent=("--resume", "rmtree"))
    assert (root / ".pnp_work").is_symlink() and _checksums(target) == {"keep.txt": _checksums(target)["keep.txt"]}
    assert sorted(p.name for p in target.iterdir()) == ["keep.txt"]
    (root / ".pnp_work").unlink()  # what the message says to do: then the run starts
    assert cli.main(_args(root, 1)) == 0


# ------------------------------------------------------------------------------------- the advice it gives
def test_an_interrupted_overwrite_advises_a_command_that_finishes_it(tmp_path, monkeypatch):
    """`generate --overwrite` stopped: "the same command with --resume" would be refused (not both flags)."""
    from lerobot_pnp.dataset import generation

    root = tmp_path / "R"
    cfg = {"repo_id": REPO, "root": str(root), "workers": 1, "progress": False}
    generate(GenerateConfig(**cfg, num_episodes=1))
    real = generation.merge_and_commit

    def stopped(*args):
        raise KeyboardInterrupt

    monkeypatch.setattr(generation, "merge_and_commit", stopped)
    with pytest.raises(DatasetError, match="interrupted") as err:
        generate(GenerateConfig(**cfg, num_episodes=2, overwrite=True))
    assert "--resume in place of --overwrite" in str(err.value) and "\n" not in str(err.value)
    monkeypatch.setattr(generation, "merge_and_commit", real)
    generate(GenerateConfig(**cfg, num_episodes=2, resume=True))  # the advice, followed
    assert validate_dataset(root)["total_episodes"] == 2


# ------------------------------------------------------------------------------------- older datasets
def test_a_dataset_older_than_manifests_is_adopted_by_its_marker_and_only_then(tmp_path, capsys):
    real = tmp_path / "real"
    link = tmp_path / "link"  # the root given as a link is the user's choice: followed
    link.symlink_to(real, target_is_directory=True)
    assert cli.main(_args(link, 1)) == 0 and validate_dataset(real)["total_episodes"] == 1
    (real / MANIFEST_FILE).unlink(missing_ok=True)  # written before manifests existed
    (real / "notes.txt").write_text("keep me")
    assert cli.main(_args(link, 1, "--resume=true")) == 0  # verified, and adopted
    assert {"meta", "data"} <= _owned(real) and "notes.txt" not in _owned(real)
    (real / MANIFEST_FILE).unlink()
    assert cli.main(_args(link, 2, "--overwrite=true")) == 0
    assert validate_dataset(real)["total_episodes"] == 2 and (real / "notes.txt").read_text() == "keep me"

    # a LeRobot dataset without the marker only `generate` writes: not provably ours, nothing deleted
    (real / MANIFEST_FILE).unlink()
    (real / "meta" / "pnp_generate.json").unlink()
    before = _checksums(real)
    capsys.readouterr()
    rc = cli.main(_args(real, 1, "--overwrite=true"))
    _one_line(capsys, rc, str(real / "meta"), "--root")
    assert {k: v for k, v in _checksums(real).items() if k != MANIFEST_FILE} == before
