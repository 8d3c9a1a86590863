"""`lerobot-pnp report --executor slurm`: the study's jobs as SLURM jobs (``report.cluster``).

On a real (one-node) cluster: a tiny study run as cluster jobs records the same evaluations, episode for episode,
as the local pool; a job cancelled with scancel fails the run in one line, and the same command then submits only
the missing stages. Needs SLURM's client binaries; a one-node cluster is started with
``benchmarks/slurm_local_cluster.sh`` when none answers and this process may (root). The grouping of the jobs
into cluster jobs is checked without SLURM.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import threading
import time
from pathlib import Path

import pytest

from lerobot_pnp import cli
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.report.cluster import cluster_tasks
from lerobot_pnp.report.schedule import TRAINING, Job

_MISSING = [b for b in ("sbatch", "squeue", "sinfo", "scancel") if shutil.which(b) is None]
needs_slurm = pytest.mark.skipif(bool(_MISSING), reason=f"SLURM is not installed ({', '.join(_MISSING)} not on PATH)")
STUDY = ["--preset", "quick", "--num_episodes", "10", "--epochs", "1", "--train_seeds", "[1000]",
         "--methods", "[lookup_table,clocked_lstm]", "--cli_check_episodes", "0",
         "--suites", "[{name: nominal, n_episodes: 2}]"]  # fmt: skip


def _report(out: Path, *flags: str) -> int:
    return cli.main(["report", "--output_dir", str(out), *STUDY, *flags])


def _episodes(out: Path) -> dict[str, list]:
    return {
        p.relative_to(out).as_posix(): json.loads(p.read_text())["episodes"] for p in (out / "evals").rglob("*.json")
    }


def _submitted(out: Path) -> list[str]:
    try:
        return json.loads((out / "slurm" / "jobs.json").read_text())["job_ids"]
    except (OSError, ValueError):
        return []


@needs_slurm
@pytest.mark.slow
def test_a_study_on_slurm_equals_the_local_run_and_resubmits_only_what_a_cancelled_job_left(cluster, tmp_path, capsys):
    # the local run beside the cluster's (its own process: the test's wall clock is the longer of the two)
    out = tmp_path / "slurm"
    slurm = ["--executor", "slurm", "--slurm.partition", cluster, "--slurm.mem_per_cpu_gb", "1", "--slurm.time", "10"]
    seen: dict[str, object] = {}

    def cancel_the_training():
        """Once the study's two cluster jobs are submitted (after the dataset's), cancel the clocked LSTM's (its
        training and evaluation) before its training can finish; the folder stays locked meanwhile."""
        from lerobot_pnp.outputs import OutputError, OutputFolder

        deadline = time.time() + 120
        while len(ids := _submitted(out)) < 2 and time.time() < deadline:
            time.sleep(0.1)
        subprocess.run(["scancel", ids[-1]], check=True, timeout=30)
        seen["cancelled"] = ids[-1]
        try:
            OutputFolder(out, "a second study").close()
        except OutputError as err:
            seen["refused"] = str(err)

    watcher = threading.Thread(target=cancel_the_training)
    watcher.start()
    assert _report(out, *slurm) == 2
    watcher.join()
    err = capsys.readouterr().err.strip().splitlines()[-1]  # the one line after the generation's log
    assert err.startswith("lerobot-pnp report: error: 1 of 2 cluster jobs failed or were cancelled"), err
    assert f"SLURM {seen['cancelled']}: clocked_lstm 1000" in err and "run the same command again" in err
    assert "another command is writing" in str(seen.get("refused")), seen
    done = _episodes(out)
    assert set(done) == {"evals/lookup_table/seed-/nominal.json"}  # the cancelled job left no record
    assert not (out / "train/clocked_lstm/seed1000/stage.json").exists()
    lookup = (out / "evals/lookup_table/seed-/nominal.json").stat().st_mtime_ns

    # the same command: only the cancelled job's stages are submitted (the dataset and lookup table are reused)
    assert _report(out, *slurm) == 0
    printed = capsys.readouterr().out
    assert "submitted 1 cluster jobs" in printed and "dataset dataset: cluster job" not in printed, printed
    assert len(_submitted(out)) == 1 and (out / "evals/lookup_table/seed-/nominal.json").stat().st_mtime_ns == lookup
    assert _report(tmp_path / "local", "--workers", "1") == 0  # the same study in this process's pool
    assert _episodes(out) == _episodes(tmp_path / "local")  # every evaluation, episode for episode
    assert (
        json.loads((out / "summary.json").read_text())["success"]
        == json.loads((tmp_path / "local" / "summary.json").read_text())["success"]
    )


@needs_slurm
def test_a_folder_whose_earlier_cluster_jobs_still_run_is_refused(cluster, tmp_path, capsys):
    """A submitting process that was killed leaves its jobs running: a new run on the folder waits for them."""
    job = subprocess.run(["sbatch", "--parsable", "-p", cluster, "--mem=100M", "-o", "/dev/null", "--wrap", "sleep 60"],
                         capture_output=True, text=True, check=True, timeout=30).stdout.strip()  # fmt: skip
    try:
        (tmp_path / "s" / "slurm").mkdir(parents=True)
        (tmp_path / "s" / "slurm" / "jobs.json").write_text(json.dumps({"job_ids": [job]}))
        assert _report(tmp_path / "s", "--fresh") == 2
    finally:
        subprocess.run(["scancel", job], timeout=30)
    err = capsys.readouterr().err.strip()
    assert f"still queued or running (SLURM ids {job})" in err and len(err.splitlines()) == 1, err
    assert (tmp_path / "s" / "slurm" / "jobs.json").is_file()  # --fresh cleared nothing
    # a job sbatch refuses is one line too
    assert _report(tmp_path / "p", "--executor", "slurm", "--slurm.partition", "nope") == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("lerobot-pnp report: error: sbatch refused the study's jobs") and "nope" in err, err
    assert len(err.splitlines()) == 1, err


def test_cluster_jobs_group_a_method_x_seed_and_wait_only_on_what_they_continue():
    jobs = [Job("clocked_lstm", "1", None, TRAINING), *(Job("clocked_lstm", "1", None, s) for s in "abc"),
            Job("lookup_table", "-", None, "a"), Job("recovering", "1", None, TRAINING),
            Job("recovering_dagger", "1", None, TRAINING), Job("recovering_dagger", "1", None, "a")]  # fmt: skip
    whole = cluster_tasks(jobs, 0)  # a method x seed's training and suites in one job
    assert [[j.part for j in t] for t in whole] == [[TRAINING, "a", "b", "c"], ["a"], [TRAINING], [TRAINING, "a"]]
    from lerobot_pnp.report.cluster import _waits_on

    assert _waits_on(whole) == [None, None, None, 2]  # DAgger's round waits for the training it continues
    split = cluster_tasks(jobs, 2)  # the training alone, its suites two per job, each waiting on it
    assert [[j.part for j in t] for t in split] == [[TRAINING], ["a", "b"], ["c"], ["a"], [TRAINING], [TRAINING], ["a"]]
    assert _waits_on(split) == [None, 0, 0, None, None, 4, 5]


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--executor", "ray"], "executor must be one of ('local', 'slurm'), got 'ray'"),
        (["--slurm.suites_per_job", "-1"], "slurm.suites_per_job must be an integer >= 0, got -1"),
        (["--slurm.time", "4h"], "slurm.time must be a SLURM time limit"),
        # a value that would be a line of its own in the job script, or split by sbatch
        (["--slurm.partition", "cpu\n--gres=gpu:8"], "slurm.partition may hold only letters, digits"),
        (["--slurm.job_name", "study\nrm -rf ~"], "slurm.job_name may hold only letters, digits, '_', '-' and '.'"),
        (["--slurm.qos", "high prio"], "slurm.qos may hold only letters, digits, '_', '-' and '.', got 'high prio'"),
        (["--slurm.partition", ""], "slurm.partition may hold only"),
    ],
)
def test_bad_executor_options_are_one_line(flags, message, tmp_path, capsys):
    assert _report(tmp_path / "never", *flags) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "never").exists()


def test_a_newline_in_a_slurm_name_from_a_config_file_is_one_line(tmp_path, capsys):
    config = tmp_path / "study.json"
    config.write_text(json.dumps({"slurm": {"partition": "cpu\n#SBATCH --gres=gpu:8"}}))
    assert _report(tmp_path / "never", "--config_path", str(config)) == 2
    err = capsys.readouterr().err.strip()
    assert "slurm.partition may hold only" in err and "'cpu\\n#SBATCH" in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "never").exists()


def test_slurm_names_sbatch_reads_as_one_name_are_accepted():
    from lerobot_pnp.report.slurm import StudySlurmOptions
    from lerobot_pnp.support.slurm_fields import check_slurm_field

    options = StudySlurmOptions(partition="cpu,gpu-a100", job_name="pnp_study.v2", qos=None)
    assert (options.partition, options.job_name, options.qos) == ("cpu,gpu-a100", "pnp_study.v2", None)
    for name, value in [("partition", "cpu,"), ("qos", ""), ("job_name", None), ("partition", "a\tb")]:
        with pytest.raises(ConfigError, match=f"^slurm.{name} may hold only") as err:
            check_slurm_field(name, value)
        assert "\n" not in str(err.value)
