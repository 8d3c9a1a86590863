"""A real SLURM run of `generate --executor slurm`: the merged dataset equals the local run's, hash for hash.

Needs SLURM's client binaries; a one-node cluster is started with ``benchmarks/slurm_local_cluster.sh``
when none answers and this process may (root). Skipped only where SLURM is not installed.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from lerobot_pnp.dataset import GenerateConfig, SlurmOptions, data_hash, generate, verify_dataset
from lerobot_pnp.errors import DatasetError

_MISSING = [b for b in ("sbatch", "squeue", "sinfo") if shutil.which(b) is None]
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(bool(_MISSING), reason=f"SLURM is not installed ({', '.join(_MISSING)} not on PATH)"),
]


def _wait_complete(root: Path, job_ids: list[str], timeout: float = 300) -> None:
    deadline = time.time() + timeout
    while time.time() < deadline:
        if (root / "meta" / "info.json").is_file() and not (root / ".pnp_work").exists():
            return
        time.sleep(1)
    queue = subprocess.run(["squeue"], capture_output=True, text=True).stdout
    raise AssertionError(f"SLURM generation did not finish in {timeout} s; squeue:\n{queue}")


def test_slurm_run_equals_local_run(cluster, tmp_path):
    n = 4
    local = generate(GenerateConfig(repo_id="test/slurm", root=str(tmp_path / "local"), num_episodes=n,
                                    tasks=1, workers=1, progress=False))  # fmt: skip
    root = tmp_path / "slurm"
    submitted = generate(
        GenerateConfig(
            repo_id="test/slurm",
            root=str(root),
            num_episodes=n,
            tasks=2,
            executor="slurm",
            slurm=SlurmOptions(partition=cluster, time="00:10:00", mem_per_cpu_gb=1, job_name="pnp_test"),
            progress=False,
        )
    )
    assert submitted["status"] == "submitted" and len(submitted["job_ids"]) == 2, submitted
    assert json.loads((root / ".pnp_work" / "slurm.json").read_text())["job_ids"] == submitted["job_ids"]
    # the submitting process has exited: the queued/running jobs themselves guard the root against --overwrite
    with pytest.raises(DatasetError, match="still queued or running"):
        generate(GenerateConfig(repo_id="test/slurm", root=str(root), num_episodes=n, overwrite=True, progress=False))
    _wait_complete(root, submitted["job_ids"])
    info = verify_dataset(root)
    assert info["total_episodes"] == n and local["episodes"] == n
    assert data_hash(root) == data_hash(tmp_path / "local")
    logs = Path(submitted["logging_dir"])
    assert len(list((logs / "shards" / "completions").iterdir())) == 2  # datatrove's records, one per rank
    assert (root / "meta" / "baxter_pnp_env.json").is_file()
    # --resume on the finished dataset: verified and reported, nothing resubmitted
    again = generate(GenerateConfig(repo_id="test/slurm", root=str(root), num_episodes=n, executor="slurm",
                                    resume=True, progress=False))  # fmt: skip
    assert again["status"] == "already complete"
