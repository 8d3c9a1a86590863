"""``lerobot-pnp report --executor slurm``: the study's SLURM options (``--slurm.*``), named as generation's.

The options extend generation's ``SlurmOptions`` (partition, CPUs, memory, time, QOS, job name), so that one
cluster's flags read the same for ``generate`` and ``report``; what the study's jobs add is how they are grouped
into cluster jobs. The executor itself: ``report.cluster``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from lerobot_pnp.dataset.executors import SlurmOptions
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.support.slurm_fields import check_slurm_fields

EXECUTORS = ("local", "slurm")
# sbatch --time: minutes, MM:SS, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS
_TIME = re.compile(r"^(\d+-\d+(:\d+){0,2}|\d+(:\d+){0,2})$")


@dataclass
class StudySlurmOptions(SlurmOptions):
    """``--slurm.*``: the resources of each cluster job of the study, and how its work is grouped into jobs."""

    partition: str = "cpu"  # SLURM partition (sbatch --partition) of every job of the study
    cpus_per_task: int = 1  # CPUs per job (sbatch --cpus-per-task): its suites are evaluated in that many processes
    mem_per_cpu_gb: int = 2  # GB per CPU (an integer: sbatch rejects "1.5G")
    time: str = "04:00:00"  # per job (sbatch --time): HH:MM:SS or D-HH:MM:SS; the longest training must fit
    job_name: str = "pnp_study"  # SLURM job name of every job of the study
    # suites per cluster job: 0 = a method x seed's training and all its suites in one job (fewest jobs: a job's
    # start costs about as long as a suite); N = the training alone, then its suites N per job (afterok)
    suites_per_job: int = 0
    dataset_cpus: int = 0  # CPUs of a dataset's generation job (its shard workers); 0 = cpus_per_task

    def __post_init__(self):
        super().__post_init__()
        check_slurm_fields(self)  # each a line of the job script: a newline there would be a line of its own
        if not isinstance(self.suites_per_job, int) or self.suites_per_job < 0:
            raise ConfigError(f"slurm.suites_per_job must be an integer >= 0, got {self.suites_per_job!r}")
        if not isinstance(self.dataset_cpus, int) or self.dataset_cpus < 0:
            raise ConfigError(f"slurm.dataset_cpus must be an integer >= 0, got {self.dataset_cpus!r}")
        if not _TIME.match(str(self.time)):
            raise ConfigError(
                f"slurm.time must be a SLURM time limit such as 04:00:00 or 1-00:00:00, got {self.time!r}"
            )


def checked(executor: str, slurm) -> tuple[str, StudySlurmOptions]:
    """The executor and its options, as ``StudyConfig`` keeps them (a dict from a config file made options)."""
    if executor not in EXECUTORS:
        raise ConfigError(f"executor must be one of {EXECUTORS}, got {executor!r}")
    return executor, StudySlurmOptions(**slurm) if isinstance(slurm, dict) else slurm
