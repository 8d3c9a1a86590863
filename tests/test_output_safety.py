"""What a command deletes, overwrites or evaluates in an output folder: only what it provably wrote there.

Every name or path read from a file in an output folder (the study's manifest, a stage record, a generation's
``run.json``) is untrusted input: a copied, downloaded or hand-edited folder must never make ``--fresh``,
a re-generation or an evaluation reach outside the folder, and a mistyped flag must never delete finished work.
Unit-level calls on tiny fake folders: no study or generation runs here.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lerobot_pnp import cli
from lerobot_pnp.cache import Stage
from lerobot_pnp.errors import ConfigError, DatasetError, OtherSettingsError
from lerobot_pnp.outputs import MANIFEST_FILE, OutputFolder
from lerobot_pnp.report.folder import COMMAND


def _tree(root: Path) -> dict[str, str]:
    """Every file under ``root`` (relative name -> text): what must survive a refused delete."""
    return {str(p.relative_to(root)): p.read_text() for p in sorted(root.rglob("*")) if p.is_file()}


def _manifest(out: Path, entries) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / MANIFEST_FILE).write_text(json.dumps({"command": COMMAND, "entries": entries}))


def _one_line(err: BaseException) -> str:
    text = str(err)
    assert "\n" not in text, text
    return text


# ------------------------------------------------------------------------------------------- --fresh, manifest
def _no_study(monkeypatch):
    """Stops a study right after its folders are cleared: what ``--fresh`` deleted is then on display."""
    from lerobot_pnp.report import run

    def stop(*args, **kwargs):
        raise RuntimeError("stopped before any stage")

    monkeypatch.setattr(run, "_prepare", stop)


def _fresh_study(out: Path, **changes):
    from lerobot_pnp.report.run import StudyConfig, run_study

    return run_study(StudyConfig(output_dir=str(out), preset="quick", fresh=True, **changes))


@pytest.mark.parametrize("entry", ["..", "../victim", "VICTIM_ABS", "a/b", ".", "", 5, None, ["x"]])
def test_fresh_refuses_a_manifest_entry_that_is_not_a_plain_name_inside_the_folder(tmp_path, monkeypatch, entry):
    _no_study(monkeypatch)
    parent = tmp_path / "parent"
    out, victim, victim_abs = parent / "s", parent / "victim", tmp_path / "victim_abs"
    for folder in (victim, victim_abs, out / "a" / "b"):
        folder.mkdir(parents=True)
        (folder / "f").write_text("x")
    _manifest(out, ["dataset", str(victim_abs) if entry == "VICTIM_ABS" else entry])
    before = _tree(tmp_path)
    with pytest.raises(ConfigError) as err:
        _fresh_study(out)
    assert MANIFEST_FILE in _one_line(err.value)
    assert _tree(tmp_path) == before  # nothing deleted, inside the folder or out of it


@pytest.mark.parametrize("text", ["{", "[]", '{"entries": "dataset"}', '{"command": "x"}', "\xff"])
def test_a_manifest_that_is_unreadable_or_not_a_manifest_is_refused_not_read_as_empty(tmp_path, monkeypatch, text):
    _no_study(monkeypatch)
    out = tmp_path / "s"
    (out / "dataset").mkdir(parents=True)
    (out / "dataset" / "f").write_text("x")
    (out / MANIFEST_FILE).write_text(text)
    with pytest.raises(ConfigError) as err:
        _fresh_study(out)
    assert "not a manifest" in _one_line(err.value)
    assert (out / "dataset" / "f").read_text() == "x"


def test_fresh_unlinks_a_linked_entry_and_never_follows_it(tmp_path, monkeypatch):
    _no_study(monkeypatch)
    out, victim = tmp_path / "s", tmp_path / "victim"
    victim.mkdir()
    (victim / "f").write_text("x")
    _manifest(out, ["dataset", "report.md"])
    (out / "dataset").symlink_to(victim, target_is_directory=True)
    (out / "report.md").symlink_to(victim / "f")
    with pytest.raises(RuntimeError, match="stopped before any stage"):
        _fresh_study(out)
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST_FILE]
    assert _tree(victim) == {"f": "x"}
    _manifest(tmp_path / "other", ["f"])  # a manifest that is a link: another folder's list, never read as ours
    (out / MANIFEST_FILE).unlink()
    (out / MANIFEST_FILE).symlink_to(tmp_path / "other" / MANIFEST_FILE)
    with pytest.raises(ConfigError, match="is a link"):
        _fresh_study(out)


def test_a_bad_manifest_of_a_study_alongside_stops_fresh_before_any_folder_is_cleared(tmp_path, monkeypatch):
    _no_study(monkeypatch)
    first, second = tmp_path / "a", tmp_path / "b"
    _manifest(first, ["report.md"])
    (first / "report.md").write_text("first study's")
    _manifest(second, ["../a"])
    (tmp_path / "b.json").write_text(json.dumps({"output_dir": str(second), "preset": "quick"}))
    with pytest.raises(ConfigError, match="not a plain name"):
        _fresh_study(first, alongside=[str(tmp_path / "b.json")])
    assert (first / "report.md").read_text() == "first study's"


# ------------------------------------------------------------------------------------- a folder older than manifests
def _older_study(out: Path) -> None:
    """A study folder written before manifests: its config, a dataset and an evaluation of its own."""
    (out / "dataset_dense" / "meta").mkdir(parents=True)
    record = {"generation": {"repo_id": "local/dataset_dense", "seed": 0, "num_episodes": 2}}
    (out / "dataset_dense" / "meta" / "pnp_generate.json").write_text(json.dumps(record))
    (out / "evals" / "expert" / "seed-").mkdir(parents=True)
    (out / "evals" / "expert" / "seed-" / "nominal.json").write_text(
        json.dumps({"key": "k", "parts": {"stage": "eval"}, "episodes": []})
    )
    (out / "study_config.json").write_text("{}")


def test_an_older_study_folder_claims_what_the_study_wrote_and_never_a_users_dataset_folder(tmp_path, monkeypatch):
    from lerobot_pnp.report.run import StudyConfig, run_study

    _no_study(monkeypatch)
    out = tmp_path / "s"
    _older_study(out)
    (out / "dataset_mine").mkdir()
    (out / "dataset_mine" / "thesis.tex").write_text("mine")
    with pytest.raises(RuntimeError, match="stopped before any stage"):
        run_study(StudyConfig(output_dir=str(out), preset="quick"))
    assert OutputFolder(out, COMMAND, lock=False).entries == {"study_config.json", "dataset_dense", "evals"}
    with pytest.raises(RuntimeError, match="stopped before any stage"):  # --fresh deletes those, and only those
        _fresh_study(out)
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST_FILE, "dataset_mine"]
    assert (out / "dataset_mine" / "thesis.tex").read_text() == "mine"


# --------------------------------------------------------------------------------- a mistyped flag and a dataset
def _finished_dataset(root: Path) -> dict[str, str]:
    """A stand-in for a finished dataset without its stage record (as every folder older than stage keys), with
    the two records every generation writes (what proves it is the generator's, where it has no manifest)."""
    names = ("meta/info.json", "meta/pnp_generate.json", "meta/baxter_pnp_env.json", "data/chunk-000/file-000.parquet")
    for name in names:
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(name)
    return _tree(root)


def test_a_mistyped_flag_leaves_a_finished_dataset_untouched(tmp_path):
    from lerobot_pnp.report.config import StudyConfig
    from lerobot_pnp.report.stages import dataset_stage

    out = tmp_path / "q"
    before = _finished_dataset(out / "dataset")
    with pytest.raises(ConfigError, match=r"workers must be an integer >= 0 .*got -1"):
        StudyConfig(output_dir=str(out), preset="quick", workers=-1, num_episodes=100)
    # ... and a bad value that reaches the generator anyway (a config built in code) touches nothing either
    cfg = StudyConfig(output_dir=str(out), preset="quick", workers=1, num_episodes=100)
    cfg.workers = -1
    with pytest.raises(ConfigError, match="workers must be >= 0, got -1") as err:
        dataset_stage(out, "dataset", cfg)
    assert not isinstance(err.value, OtherSettingsError)
    assert _tree(out / "dataset") == before


def test_a_dataset_made_with_other_settings_is_replaced_and_any_other_error_touches_nothing(tmp_path, monkeypatch):
    from lerobot_pnp.report import adapters
    from lerobot_pnp.report.config import StudyConfig
    from lerobot_pnp.report.stages import dataset_stage

    out = tmp_path / "q"
    cfg = StudyConfig(output_dir=str(out), preset="quick", workers=1, num_episodes=20)
    calls = []

    def generate(*args, **kwargs):  # the generator's verification, then a fresh recording
        calls.append(args)
        if len(calls) == 1:
            raise OtherSettingsError("--resume with different settings than the run on disk (num_episodes: 10 vs 20)")
        return {"status": "generated"}

    monkeypatch.setattr(adapters, "generate_dataset", generate)
    _finished_dataset(out / "dataset")
    assert dataset_stage(out, "dataset", cfg)[0] == {"status": "generated"} and len(calls) == 2
    assert _tree(out / "dataset") == {"stage.json": (out / "dataset" / "stage.json").read_text()}

    def refuse(*args, **kwargs):
        raise ConfigError("some other configuration error")

    (out / "dataset" / "stage.json").unlink()
    before = _finished_dataset(out / "dataset")
    monkeypatch.setattr(adapters, "generate_dataset", refuse)
    with pytest.raises(ConfigError, match="some other"):
        dataset_stage(out, "dataset", cfg)
    assert _tree(out / "dataset") == before


def test_a_regeneration_deletes_only_a_dataset_the_generator_provably_wrote(tmp_path):
    """A LeRobot dataset without the generator's records (and no manifest) is not the generator's to delete."""
    from lerobot_pnp.dataset.workdir import remove_generation

    root = tmp_path / "dataset"
    _finished_dataset(root)
    (root / "meta" / "baxter_pnp_env.json").unlink()
    (root / "notes.txt").write_text("mine")
    before = _tree(root)
    with pytest.raises(ConfigError, match="meta") as err:
        remove_generation(root)
    assert "--root" in _one_line(err.value)
    assert {k: v for k, v in _tree(root).items() if k != MANIFEST_FILE} == before
    (root / "meta" / "baxter_pnp_env.json").write_text("{}")  # the generator's: its entries go, the user's stay
    remove_generation(root)
    assert _tree(root) == {"notes.txt": "mine"}


# --------------------------------------------------------------------------------------- paths in stage records
@pytest.mark.parametrize("field", ["artifact", "checkpoint"])
@pytest.mark.parametrize("value", ["ABSOLUTE", "../other/pretrained_model", "", 3, "LINK_OUT"])
def test_a_record_naming_an_output_outside_its_folder_is_not_trusted(tmp_path, capsys, field, value):
    elsewhere = tmp_path / "elsewhere" / "pretrained_model"
    elsewhere.mkdir(parents=True)
    folder = tmp_path / "train" / "seed1"
    folder.mkdir(parents=True)
    (folder / "ckpt").symlink_to(elsewhere, target_is_directory=True)
    value = {"ABSOLUTE": str(elsewhere), "LINK_OUT": "ckpt"}.get(value, value)
    stage = Stage(folder / "stage.json", {"stage": "train", "seed": 1})
    stage.commit(**{field: value})
    assert stage.stored() is None
    assert not stage.done("training m seed1")
    out = capsys.readouterr().out
    assert "not trusted" in out and field in out


def test_a_training_record_without_its_artefact_is_stale_and_a_good_one_is_reused(tmp_path, capsys):
    folder = tmp_path / "seed1"
    stage = Stage(folder / "stage.json", {"stage": "train", "seed": 1})
    stage.commit()  # as a record whose "artifact" was removed by hand
    assert stage.stored() is None and not stage.done("training m seed1")
    assert "names no trained artefact" in capsys.readouterr().out
    (folder / "checkpoints" / "000002" / "pretrained_model").mkdir(parents=True)
    (folder / "checkpoints" / "last").symlink_to("000002")  # LeRobot's own link, inside the folder
    stage.commit(artifact="checkpoints/last/pretrained_model")
    assert stage.done() and stage.stored()["artifact"] == "checkpoints/last/pretrained_model"
    assert Stage(folder / "eval.json", {"stage": "eval"}).stored() is None  # no record: nothing to say
    assert capsys.readouterr().out == ""


# ----------------------------------------------------------------------------------- a generation's run.json
def _run_record(**changes) -> dict:
    from lerobot_pnp.dataset import GenerateConfig

    return {**GenerateConfig(repo_id="t/s", num_episodes=2).run_record(1), **changes}


@pytest.mark.parametrize(
    ("changes", "says"),
    [
        ({"env": None}, "env"),
        ({"env": []}, "env"),
        ({"tasks": 1e9}, "tasks"),
        ({"tasks": 3}, "tasks"),
        ({"tasks": 0}, "tasks"),
        ({"seed": "0"}, "seed"),
        ({"num_episodes": True}, "num_episodes"),
        ({"train_fraction": 2}, "train_fraction"),
    ],
)
def test_a_hand_edited_run_record_is_refused_in_one_line(tmp_path, changes, says):
    from lerobot_pnp.dataset import GenerateConfig, generate

    root = tmp_path / "d"
    (root / ".pnp_work").mkdir(parents=True)
    record = _run_record(**changes)
    if changes.get("env", {}) is None:
        del record["env"]
    (root / ".pnp_work" / "run.json").write_text(json.dumps(record))
    with pytest.raises(DatasetError, match=says) as err:
        generate(GenerateConfig(repo_id="t/s", root=str(root), num_episodes=2, resume=True, progress=False))
    assert "--overwrite" in _one_line(err.value)
    (root / ".pnp_work" / "run.json").write_text("[1, 2]")
    with pytest.raises(DatasetError, match="JSON object"):
        generate(GenerateConfig(repo_id="t/s", root=str(root), num_episodes=2, resume=True, progress=False))


def test_a_generation_failing_before_its_first_episode_leaves_nothing(tmp_path, monkeypatch):
    from lerobot_pnp.dataset import GenerateConfig, generation

    def unreachable(step, tasks, workers, logs):
        raise DatasetError("shard 0: env: object box corner (3.000, 3.000) is out of the arm's reach")

    monkeypatch.setattr(generation, "run_local", unreachable)
    root = tmp_path / "new" / "d"
    with pytest.raises(DatasetError, match="reach") as err:
        generation.generate(GenerateConfig(repo_id="t/s", root=str(root), num_episodes=2, workers=1, progress=False))
    assert "task logs" not in str(err.value)  # they went with the work folder
    assert not root.exists()
    assert not root.parent.exists()  # nor the folder made to hold it
    kept = tmp_path / "kept"
    kept.mkdir()
    with pytest.raises(DatasetError, match="reach"):
        generation.generate(GenerateConfig(repo_id="t/s", root=str(kept), num_episodes=2, workers=1, progress=False))
    assert list(kept.iterdir()) == []  # the folder was there before: it stays, as it was

    def one_then_unreachable(step, tasks, workers, logs):
        (Path(step.work) / "progress").mkdir(parents=True, exist_ok=True)
        (Path(step.work) / "progress" / "00000").write_text("1 0")
        unreachable(step, tasks, workers, logs)

    monkeypatch.setattr(generation, "run_local", one_then_unreachable)
    with pytest.raises(DatasetError, match="task logs"):  # an episode was written: kept for --resume
        generation.generate(GenerateConfig(repo_id="t/s", root=str(root), num_episodes=2, workers=1, progress=False))
    assert (root / ".pnp_work" / "run.json").is_file()


# ----------------------------------------------------------------------------------- advice for the output folder
@pytest.mark.parametrize("command", ["report", "dagger"])
def test_an_output_dir_that_is_a_file_or_read_only_gets_advice_the_command_has(tmp_path, capsys, monkeypatch, command):
    afile = tmp_path / "afile"
    afile.write_text("mine")
    assert cli.main([command, "--output_dir", str(afile)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "is a file" in err and "--resume" not in err, err
    assert afile.read_text() == "mine"
    import os

    folder = tmp_path / "ro"
    folder.mkdir()
    monkeypatch.setattr(os, "access", lambda path, mode: Path(path) != folder)  # root ignores file modes
    assert cli.main([command, "--output_dir", str(folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot write" in err and "--resume" not in err, err
    assert list(folder.iterdir()) == []


@pytest.mark.parametrize("text", ["{}", "[]", '{"wall_s": "1"}', '{"wall_s": NaN}', "{", '{"wall_s": true}'])
def test_a_hand_edited_training_time_is_left_out_not_a_traceback(tmp_path, text):
    from lerobot_pnp.report.job import TRAIN_TIME, train_time

    (tmp_path / TRAIN_TIME).write_text(text)
    assert train_time(tmp_path) is None
    (tmp_path / TRAIN_TIME).write_text('{"wall_s": 12}')
    assert train_time(tmp_path) == 12.0


def test_dagger_keeps_its_demonstrations_record_when_the_generator_refuses_the_settings(tmp_path, monkeypatch):
    import lerobot_pnp.dataset as dataset
    from lerobot_pnp.dagger import loop
    from lerobot_pnp.dagger.config import DaggerConfig

    cfg = DaggerConfig(output_dir=str(tmp_path), num_episodes=4)
    record = tmp_path / "demos" / "stage.json"
    record.parent.mkdir()
    record.write_text(json.dumps({"key": "k", "parts": {"stage": "demos", "seed": 99}}))  # another seed: stale

    def refuse(**kwargs):
        raise ConfigError("num_episodes must be an integer >= 1, got 0")

    monkeypatch.setattr(dataset, "GenerateConfig", refuse)
    with pytest.raises(ConfigError, match="num_episodes"):
        loop._demos(cfg, tmp_path, loop.base_env_config(cfg))
    assert record.is_file()
