"""`lerobot-pnp report` / `demo` in an output folder that holds more than the study: the study writes, replaces and
deletes (``--fresh``) only what it wrote; SLURM missing, or an interrupt, leaves nothing new and one line that
names what exists. The generator, the trainings and the job pool are stand-ins: no study runs here."""

from __future__ import annotations

import errno
import hashlib
import json
from pathlib import Path

import pytest

from lerobot_pnp import cli
from lerobot_pnp.errors import DatasetError, OtherSettingsError
from lerobot_pnp.outputs import MANIFEST_FILE, OutputFolder
from lerobot_pnp.report import adapters, cluster, run
from lerobot_pnp.report.folder import COMMAND

S = ["--preset", "quick", "--num_episodes", "20", "--epochs", "2", "--workers", "1"]


def _report(out: Path, *flags: str) -> int:
    return cli.main(["report", *S, "--output_dir", str(out), *flags])


def _sums(root: Path) -> dict[str, str]:
    """Every file under ``root`` (relative name -> sha256): what must survive a refused run."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() for p in root.rglob("*") if p.is_file()
    }


def _users_dataset(root: Path) -> None:
    """A dataset `lerobot-pnp generate --root X/dataset` made (its files, as the generator lays them out)."""
    for name in (
        "meta/info.json",
        "meta/pnp_generate.json",
        "meta/baxter_pnp_env.json",
        "data/chunk-000/file-000.parquet",
        "videos/c.mp4",
    ):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(f"the user's {name}")


def _error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


@pytest.fixture
def generator(monkeypatch):
    """The generator as it answers a dataset of other settings: it names the setting, and a second recording
    fails (a camera dataset this machine cannot render). Records each call's root."""
    calls: list[Path] = []

    def generate(root, *args, **kwargs):
        calls.append(Path(root))
        if len(calls) == 1:
            raise OtherSettingsError("--resume with different settings than the run on disk (num_episodes: 2 vs 20)")
        raise DatasetError("cannot render the cameras here")

    monkeypatch.setattr(adapters, "generate_dataset", generate)
    return calls


def test_a_users_dataset_in_the_output_dir_is_refused_and_left_intact(tmp_path, capsys, generator):
    _users_dataset(tmp_path / "dataset")
    before = _sums(tmp_path)
    assert _report(tmp_path) == 2
    err = _error(capsys)
    assert "dataset" in err and "did not write" in err, err
    assert _sums(tmp_path) == before and generator == []
    assert _report(tmp_path, "--fresh", "true") == 2  # --fresh never deletes it either
    assert _sums(tmp_path) == before and "dataset" in _error(capsys)


def test_a_dataset_the_study_wrote_is_reused_or_replaced_by_it(tmp_path, monkeypatch, generator):
    with OutputFolder(tmp_path, COMMAND) as folder:  # an earlier study's dataset
        folder.claim("dataset")
        _users_dataset(tmp_path / "dataset")

    def stop(runs):
        raise RuntimeError("the datasets are done")

    monkeypatch.setattr(run, "_run_prepared", stop)
    with pytest.raises(DatasetError, match="cannot render"):  # the generator was asked, as for any study dataset
        run.run_study(run.StudyConfig(output_dir=str(tmp_path), preset="quick", num_episodes=20, workers=1))
    assert generator == [tmp_path / "dataset", tmp_path / "dataset"]


def test_a_users_train_folder_is_refused_and_fresh_never_deletes_it(tmp_path, capsys, monkeypatch):
    (tmp_path / "train" / "r").mkdir(parents=True)
    (tmp_path / "train" / "r" / "model.safetensors").write_bytes(b"weights")

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(adapters, "generate_dataset", interrupted)  # a run that gets going is stopped at once
    for fresh in ("false", "true"):
        assert _report(tmp_path, "--fresh", fresh) == 2
        err = _error(capsys)
        assert "train" in err and "did not write" in err, err
        assert (tmp_path / "train" / "r" / "model.safetensors").read_bytes() == b"weights"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["train"]  # nothing written: no config, no manifest


def test_slurm_missing_is_one_line_before_anything_is_written(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cluster, "slurm_available", lambda: False)
    assert _report(tmp_path / "new", "--executor", "slurm") == 2
    assert "sbatch" in _error(capsys)
    assert not (tmp_path / "new").exists()
    (tmp_path / "old").mkdir()
    assert _report(tmp_path / "old", "--executor", "slurm") == 2
    assert list((tmp_path / "old").iterdir()) == []


def test_an_interrupted_study_says_that_the_same_command_continues_it(tmp_path, capsys, monkeypatch):
    """Interrupted while its dataset is generated, a study says to run the same command again (``report`` has
    no ``--resume``), and that command does continue the generation (the generator is asked to resume)."""
    from lerobot_pnp.dataset import generation

    resumed: list[bool] = []

    def interrupted(cfg, root, t_start):
        resumed.append(cfg.resume)
        raise KeyboardInterrupt

    monkeypatch.setattr(generation, "_generate_locked", interrupted)
    for _ in range(2):
        assert _report(tmp_path) == 2
        err = _error(capsys)
        assert "interrupted" in err and "run the same command again" in err and "--resume" not in err, err
    assert resumed == [False, True]

    def full_disk(cfg, root, t_start):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(generation, "_generate_locked", full_disk)
    assert _report(tmp_path) == 2
    err = _error(capsys)
    assert "disk is full" in err and "run the same study command again" in err and "--resume" not in err, err


def test_an_interrupt_in_training_says_the_same(tmp_path, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(run, "dataset_stage", lambda out, name, cfg, changes=None: ({"status": "reused"}, "k"))
    monkeypatch.setattr(run, "run_jobs", interrupted)
    assert _report(tmp_path) == 2
    err = _error(capsys)
    assert "interrupted" in err and "run the same command again" in err and "--resume" not in err, err
    assert json.loads((tmp_path / MANIFEST_FILE).read_text())["owners"][COMMAND]  # what it wrote is recorded
