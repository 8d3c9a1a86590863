"""The study's memory controls and the recovering planner before / after DAgger, on a tiny study."""

import json
from dataclasses import replace

import pytest

from lerobot_pnp.dagger.rollouts import TEACHER_VERSION
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.integration.recorded_task import read_recorded
from lerobot_pnp.report import methods, recipes
from lerobot_pnp.report.run import StudyConfig, SuiteSpec, run_study

N = 10  # demonstrations: 8 train / 2 test


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("methods") / "study"
    cfg = dict(
        output_dir=str(out),
        preset="quick",
        num_episodes=N,
        workers=1,
        epochs=2,
        methods=["phase_told_mlp", "recovering_dagger", "recovering_dart"],
        train_seeds=[1000],
        suites=[SuiteSpec("nominal", 2), SuiteSpec("grasp_miss", 2)],
    )
    patch = pytest.MonkeyPatch()  # kept for the module's tests: a re-run must find the same schedule
    for name in ("recovering_dagger", "recovering_dart"):  # 3 rollouts, not the study's 300
        m = methods.METHODS[name]
        patch.setitem(methods.METHODS, name, replace(m, schedule={**m.schedule, "rollouts_per_round": 3}))
    try:
        yield out, cfg, run_study(StudyConfig(**cfg))
    finally:
        patch.undo()


def test_phase_told_control_trains_on_the_same_demonstrations_with_the_phase_observed(study):
    from lerobot_pnp.report.adapters import check_same_demonstrations

    out, _, _ = study
    assert read_recorded(out / "dataset_phase")["observe_phase"] is True
    assert check_same_demonstrations(out / "dataset", out / "dataset_phase") == N
    ckpt = json.loads((out / "train/phase_told_mlp/seed1000/checkpoints/last/pretrained_model/config.json").read_text())
    assert ckpt["input_features"]["observation.environment_state"]["shape"] == [3 + 10]  # xyz + phase one-hot
    assert ckpt["recurrent"] is False and ckpt["mode"] == "recovering"
    evaluated = json.loads((out / "evals/phase_told_mlp/seed1000/nominal.json").read_text())
    assert all(part["observe_phase"] for part in evaluated["env_parts"])


def test_dagger_continues_the_recovering_run_of_the_same_seed(study):
    out, _, _ = study
    round0 = out / "train/recovering/seed1000/checkpoints/last/pretrained_model"
    assert (round0 / "model.safetensors").is_file()  # trained once, as the method `recovering` of the report
    dagger = out / "train/recovering_dagger/seed1000"
    assert not (dagger / "round_00" / "train").exists()  # round 0 was not trained again
    # Ross et al.'s mixture: the expert executes every step of round 1, half of round 2's
    betas = [json.loads((dagger / f"round_0{r}" / "rollouts.json").read_text())["beta"] for r in (1, 2)]
    assert betas == [1.0, 0.5] and recipes.DAGGER_ROUNDS == 2
    assert json.loads((dagger / "round_01" / "rollouts.json").read_text())["episodes"] == 3
    # each round continues the previous round's weights (warm start): each round's training is keyed by the checkpoint it starts from
    warm = [json.loads((dagger / f"round_0{r}" / "train" / "done.json").read_text())["parts"] for r in (1, 2)]
    assert all("init" in w for w in warm)
    # at most the study's epochs (2 here; 100 of 300 in the paper study): never dearer than a retraining
    assert warm[0]["epochs"] == warm[1]["epochs"] == min(recipes.DAGGER_WARM_START_EPOCHS, 2) == 2
    # the schedule is part of the method's training key: another mixture would train again
    stage = json.loads((dagger / "stage.json").read_text())
    assert stage["parts"]["schedule"]["beta"] == 1.0 and stage["parts"]["schedule"]["rollouts_per_round"] == 3
    # so is the teacher's version, as in the rollouts where the policy acts (round 2), not where the expert does
    assert stage["parts"]["teacher"] == TEACHER_VERSION
    rounds = [json.loads((dagger / f"round_0{r}" / "rollouts.json").read_text()) for r in (1, 2)]
    assert "teacher" not in rounds[0]["parts"] and rounds[1]["parts"]["teacher"] == TEACHER_VERSION
    recorded = read_recorded(dagger / "round_02" / "rollouts")
    assert recorded["keyframe_budget"] == 20  # room to recover in the rollouts
    for suite in ("nominal", "grasp_miss"):
        assert len(json.loads((out / f"evals/recovering_dagger/seed1000/{suite}.json").read_text())["episodes"]) == 2


def test_dart_continues_the_same_run_with_noisy_expert_demonstrations_of_the_undisturbed_task(study):
    out, _, _ = study
    rollouts = json.loads((out / "train/recovering_dart/seed1000/round_01/rollouts.json").read_text())
    assert rollouts["episodes"] == 3 and rollouts["beta"] == 1.0  # the expert acts at every step
    assert rollouts["dart"]["sigma"] == recipes.DART_SIGMA
    assert "teacher" not in json.loads((out / "train/recovering_dart/seed1000/stage.json").read_text())["parts"]
    assert not (out / "train/recovering_dart/seed1000/round_00/train").exists()  # the recovering run of the seed
    recorded = read_recorded(out / "train/recovering_dart/seed1000/round_01/rollouts")
    assert recorded["grasp_miss_prob"] == recorded["drop_prob"] == recorded["displace_prob"] == 0.0  # undisturbed
    assert len(json.loads((out / "evals/recovering_dart/seed1000/grasp_miss.json").read_text())["episodes"]) == 2


def test_finished_evaluations_are_reused_unless_their_suite_changed(study):
    out, cfg, _ = study
    files = {p: p.stat().st_mtime_ns for p in (out / "evals").rglob("*.json")}
    stale = out / "evals/phase_told_mlp/seed1000/grasp_miss.json"
    data = json.loads(stale.read_text())
    data["parts"]["env_parts"][0]["grasp_miss_prob"] = 0.5  # as if the suite had been defined otherwise
    stale.write_text(json.dumps(data))
    files[stale] = stale.stat().st_mtime_ns
    run_study(StudyConfig(**cfg))
    changed = {p for p, t in files.items() if p.stat().st_mtime_ns != t}
    assert changed == {stale}
    assert json.loads(stale.read_text())["env_parts"][0]["grasp_miss_prob"] == 1.0


def _wait_for_mark(log_dir, name: str, start: float) -> None:
    """Wait (up to a minute from ``start``) for another stand-in job's start mark ``name.started``."""
    import time
    from pathlib import Path

    while not Path(log_dir, f"{name}.started").exists() and time.time() - start < 60:
        time.sleep(0.05)


def _timed_job(job, log_dir):
    """A stand-in for run_job in a spawned process: records when it ran. The recovering job waits (up to a
    minute) for the other job's start mark, so a pool that runs them side by side passes however slowly a
    spawned worker starts under load, and one that runs them one after the other fails."""
    import time
    from pathlib import Path

    start = time.time()
    Path(log_dir, f"{job.method}_{job.tag}.started").touch()
    if job.method == "recovering":
        _wait_for_mark(log_dir, "clocked_lstm_1", start)
    Path(log_dir, f"{job.method}_{job.tag}").write_text(f"{start} {time.time()}")
    return job.method


def test_parallel_jobs_run_dagger_after_the_recovering_run_it_continues(tmp_path):
    from lerobot_pnp.report.schedule import Job, run_jobs

    jobs = [Job("recovering_dagger", "1", None), Job("recovering", "1", None), Job("clocked_lstm", "1", None)]
    out = dict(run_jobs(jobs, (str(tmp_path),), 2, fn=_timed_job))
    assert {j.method for j in out} == {j.method for j in jobs} and all(out[j] == j.method for j in jobs)
    start = {p.name: [float(v) for v in p.read_text().split()] for p in tmp_path.iterdir() if not p.suffix}
    assert start["recovering_dagger_1"][0] >= start["recovering_1"][1]  # waited for its round 0
    assert start["clocked_lstm_1"][0] < start["recovering_1"][1]  # the other job ran beside it


def test_a_pool_evaluates_each_suite_once_its_training_is_done(tmp_path):
    """Split for a pool, a method x seed is its training and one job per suite: the suites wait for the training
    (and DAgger's training for the run it continues), an untrained method's suites start at once, and two
    suites of one trained method run side by side."""
    from lerobot_pnp.report.schedule import TRAINING, Job, run_jobs, split_jobs

    whole = [Job("recovering", "1", None), Job("recovering_dagger", "1", None), Job("expert", "-", None)]
    jobs = split_jobs(whole, {whole[0]: ["nominal", "drop"], whole[1]: ["nominal"], whole[2]: ["nominal"]})
    assert [j.key for j in jobs] == [
        ("recovering", "1", TRAINING, 0), ("recovering", "1", "nominal", 0), ("recovering", "1", "drop", 0),
        ("recovering_dagger", "1", TRAINING, 0), ("recovering_dagger", "1", "nominal", 0), ("expert", "-", "nominal", 0),
    ]  # fmt: skip
    after = {j.key: j.after() for j in jobs}
    assert after[("recovering", "1", "drop", 0)] == ("recovering", "1", TRAINING, 0)
    assert after[("recovering_dagger", "1", TRAINING, 0)] == ("recovering", "1", TRAINING, 0)
    assert after[("recovering", "1", TRAINING, 0)] is None and after[("expert", "-", "nominal", 0)] is None

    out = dict(run_jobs(jobs, (str(tmp_path),), 2, fn=_logged_job))
    assert set(out) == set(jobs)
    span = {p.stem: [float(v) for v in p.read_text().split()] for p in tmp_path.glob("*.log")}
    trained = span["recovering_1_training"][1]
    assert span["recovering_1_nominal"][0] >= trained and span["recovering_1_drop"][0] >= trained
    assert span["recovering_dagger_1_training"][0] >= trained
    assert span["expert_-_nominal"][0] < trained  # no training to wait for
    nominal, drop = span["recovering_1_nominal"], span["recovering_1_drop"]
    assert nominal[0] < drop[1] and drop[0] < nominal[1]  # side by side


def _logged_job(job, log_dir):
    """A stand-in for run_job: records when it ran. Trainings take a while, and the recovering training waits (up
    to a minute) for the expert's start mark; the suites of the recovering run wait for each other's. So the test
    passes only if those jobs run side by side, however slowly a spawned worker starts under load."""
    import time
    from pathlib import Path

    start = time.time()
    name = f"{job.method}_{job.tag}_{job.part}"
    Path(log_dir, f"{name}.started").touch()
    if job.part == "training":
        time.sleep(1.0)
    if job.method == "recovering" and job.part == "training":
        _wait_for_mark(log_dir, "expert_-_nominal", start)
    if job.method == "recovering" and job.part in ("nominal", "drop"):
        _wait_for_mark(log_dir, f"recovering_1_{'drop' if job.part == 'nominal' else 'nominal'}", start)
    Path(log_dir, f"{name}.log").write_text(f"{start} {time.time()}")
    return job.key


def _eager_job(job, log_dir):
    """A stand-in for run_job: records when it started. The ACT training waits (up to a minute) for the start of the
    clocked net's evaluation, so one process stays busy until the pool has chosen what follows the clocked
    training: its evaluation or the next training."""
    import time
    from pathlib import Path

    start = time.time()
    name = f"{job.method}_{job.part}"
    Path(log_dir, f"{name}.started").write_text(str(start))
    if name == "act_training":
        _wait_for_mark(log_dir, "clocked_lstm_nominal", start)
    return job.key


def test_a_pool_evaluates_a_checkpoint_as_soon_as_it_exists(tmp_path):
    """Once the clocked net's training is done, its evaluation starts before the training still waiting in line:
    first results come early, and the pool stays as full (``schedule.ready``)."""
    from lerobot_pnp.report.schedule import TRAINING, Job, run_jobs

    jobs = [Job("clocked_lstm", "1", None, TRAINING), Job("shared_lstm", "1", None, TRAINING),
            Job("clocked_lstm", "1", None, "nominal"), Job("act", "1", None, TRAINING)]  # fmt: skip
    assert set(dict(run_jobs(jobs, (str(tmp_path),), 2, fn=_eager_job))) == set(jobs)
    start = {p.name.removesuffix(".started"): float(p.read_text()) for p in tmp_path.glob("*.started")}
    assert start["clocked_lstm_nominal"] < start["shared_lstm_training"]


def test_a_pool_takes_the_likely_longest_jobs_first():
    """Dense-control (ACT) jobs, then the runs DAgger/DART continue, then the recovering recipe's trainings,
    then other trainings, then evaluation-only jobs: in the listed order (ACT last) two workers would leave the
    last ACT job running alone on one core."""
    from lerobot_pnp.report.schedule import Job, longest_first

    jobs = [Job("expert", "-", None), Job("lookup_table", "-", None), Job("clocked_lstm", "1", None),
            Job("recovering_dagger", "1", None), Job("recovering", "1", None), Job("act", "1", None),
            Job("act", "2", None), Job("clocked_lstm", "n10", 10)]  # fmt: skip
    order = [(j.method, j.tag) for j in longest_first(jobs)]
    assert order == [("act", "1"), ("act", "2"), ("recovering", "1"), ("recovering_dagger", "1"),
                     ("clocked_lstm", "1"), ("clocked_lstm", "n10"), ("expert", "-"), ("lookup_table", "-")]  # fmt: skip
    # split for a pool: the suites of a trained method last (they wait for it), an untrained one's before them
    parts = [
        Job("recovering", "1", None, "nominal"),
        Job("expert", "-", None, "nominal"),
        Job("act", "1", None, "training"),
    ]
    assert [j.key for j in longest_first(parts)] == [("act", "1", "training", 0), ("expert", "-", "nominal", 0),
                                                     ("recovering", "1", "nominal", 0)]  # fmt: skip


@pytest.mark.slow
def test_studies_alongside_share_one_pool_and_keep_their_own_reports(tmp_path):
    """`alongside`: a second study's jobs run in the first one's pool (two processes, a trained method's suites
    and the cross-check as jobs of their own); each study writes its own records and report, both summaries hold
    the run's cost, and running it again redoes nothing (and says so in the cost)."""
    base = dict(preset="quick", num_episodes=N, epochs=1, train_seeds=[1000], cli_check_episodes=0)
    other = tmp_path / "other.json"
    other.write_text(json.dumps({**base, "output_dir": str(tmp_path / "b"), "methods": ["expert", "recovering"],
                                 "suites": [{"name": "nominal", "n_episodes": 2}, {"name": "drop", "n_episodes": 2}]}))  # fmt: skip
    cfg = StudyConfig(**{**base, "cli_check_episodes": 2}, output_dir=str(tmp_path / "a"), workers=2,
                      methods=["lookup_table", "recovering"], suites=[SuiteSpec("nominal", 2)], alongside=[str(other)])  # fmt: skip
    summary = run_study(cfg)
    assert summary["report"] == str(tmp_path / "a" / "report.md") and len(summary["alongside"]) == 1
    assert summary["alongside"][0]["report"] == str(tmp_path / "b" / "report.md")
    a = {p.relative_to(tmp_path / "a").as_posix() for p in (tmp_path / "a" / "evals").rglob("*.json")}
    b = {p.relative_to(tmp_path / "b").as_posix() for p in (tmp_path / "b" / "evals").rglob("*.json")}
    assert a == {"evals/lookup_table/seed-/nominal.json", "evals/recovering/seed1000/nominal.json"}
    assert b == {"evals/expert/seed-/nominal.json", "evals/expert/seed-/drop.json",
                 "evals/recovering/seed1000/nominal.json", "evals/recovering/seed1000/drop.json"}  # fmt: skip
    # the run's cost, the same in both studies' summaries: every stage, each done by this run itself
    costs = [json.loads((tmp_path / name / "summary.json").read_text())["cost"] for name in "ab"]
    assert costs[0] == costs[1] and list(costs[0]["stages"]) == ["datasets", "jobs", "cli_check", "report"]
    assert costs[0]["ran"] == {"datasets": [2, 2], "trainings": [2, 2], "evaluations": [6, 6], "cli_checks": [1, 1]}
    cli = json.loads((tmp_path / "a" / "summary.json").read_text())["lerobot_eval_cli_check"]
    assert (cli["n"], cli["agree"]) == (2, 2)  # the cross-check, run as a job of the pool, compared after it
    assert costs[0]["from_scratch"] and costs[0]["processes"] == 2 and costs[0]["disk_mb"] > 0
    files = {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*.json") if "evals" in p.parts or "train" in p.parts}
    run_study(cfg)
    assert {p for p, t in files.items() if p.stat().st_mtime_ns != t} == set()
    again = json.loads((tmp_path / "a" / "summary.json").read_text())["cost"]
    assert again["ran"] == {"datasets": [0, 2], "trainings": [0, 2], "evaluations": [0, 6], "cli_checks": [0, 1]}
    assert not again["from_scratch"]  # a resumed run's wall clock is not the study's cost
    with pytest.raises(ConfigError, match="same output_dir"):
        run_study(StudyConfig(**{**base, "output_dir": str(tmp_path / "b")}, alongside=[str(other)]))


def test_a_held_alongside_folder_stops_the_run_before_any_folder_is_cleared(tmp_path):
    """Every study's folder is locked before `--fresh` clears any: a study alongside whose folder another command
    holds stops the run at once, and the first study's files stay as they were."""
    from lerobot_pnp.outputs import OutputError, OutputFolder

    first, other = tmp_path / "a", tmp_path / "b"
    first.mkdir()
    (first / "study_config.json").write_text("{}")  # a study's file: --fresh would delete it
    (first / "evals").mkdir()
    config = tmp_path / "other.json"
    config.write_text(json.dumps({"preset": "quick", "output_dir": str(other)}))
    cfg = StudyConfig(preset="quick", output_dir=str(first), fresh=True, alongside=[str(config)])
    with OutputFolder(other, "lerobot-pnp report/demo"), pytest.raises(OutputError, match="another command is writing"):
        run_study(cfg)
    assert (first / "study_config.json").read_text() == "{}" and (first / "evals").is_dir()
