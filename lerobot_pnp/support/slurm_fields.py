"""What sbatch accepts in the SLURM options that become lines of a job script (``--slurm.partition``, ...).

The cluster executors (submitit for the study's jobs, datatrove for the generation's) write each option as one
``#SBATCH --name=value`` line of a shell script: a value holding a newline would become a line of its own (a
directive or a command of the script), and a space or a quote is split or kept by sbatch's own parser. The
names SLURM gives partitions, QOS and jobs are letters, digits, ``_``, ``-`` and ``.``; a partition option may
list several, separated by commas. Any other value is refused in one line naming the field, before anything is
written or submitted.
"""

from __future__ import annotations

import re
from typing import Any

from lerobot_pnp.errors import ConfigError, shown

_NAME = r"[A-Za-z0-9_.-]+"
# field -> (the whole value it must match, what the one-line message lists as allowed)
FIELDS: dict[str, tuple[re.Pattern, str]] = {
    "partition": (re.compile(f"{_NAME}(,{_NAME})*"), "letters, digits, '_', '-' and '.' (',' between partitions)"),
    "qos": (re.compile(_NAME), "letters, digits, '_', '-' and '.'"),
    "job_name": (re.compile(_NAME), "letters, digits, '_', '-' and '.'"),
}
OPTIONAL = ("qos",)  # None: the option is left out of the script (the cluster's default)


def check_slurm_field(name: str, value: Any, prefix: str = "slurm") -> None:
    """Refuse (one line, ``ConfigError``) a value of SLURM option ``name`` that sbatch would not read as one name."""
    if value is None and name in OPTIONAL:
        return
    pattern, allowed = FIELDS[name]
    if not isinstance(value, str) or pattern.fullmatch(value) is None:
        raise ConfigError(f"{prefix}.{name} may hold only {allowed}, got {shown(value)}")


def check_slurm_fields(options: Any, prefix: str = "slurm") -> None:
    """``check_slurm_field`` for each of ``FIELDS`` that ``options`` (a SLURM options dataclass) has."""
    for name in FIELDS:
        if hasattr(options, name):
            check_slurm_field(name, getattr(options, name), prefix)
