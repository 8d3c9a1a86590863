"""``StudyLayout``: the one owner of every path a study writes under its output folder.

The caches are found by these paths (a training by its folder, an evaluation by its JSON), so renaming one
here moves every reader and writer together; ``tests/test_report_layout.py`` pins each path to its literal.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

CLUSTER_DIR = "slurm"  # the cluster jobs' folder (``--executor slurm``): submitit's job folders, the submitted ids


@dataclass(frozen=True)
class StudyLayout:
    out: Path

    @property
    def config(self) -> Path:
        """The study's resolved config (``StudyConfig`` as JSON)."""
        return self.out / "study_config.json"

    def dataset(self, recording: str = "keyframe") -> Path:
        """The expert's demonstrations; another recording of them (``Method.data``) beside it."""
        return self.out / ("dataset" if recording == "keyframe" else f"dataset_{recording}")

    def train(self, method: str, tag: str) -> Path:
        """A method's training folder for one training seed or data-efficiency tag (``Job.tag``)."""
        return self.out / "train" / method / f"seed{tag}"

    def eval_record(self, method: str, tag: str, suite: str) -> Path:
        """The evaluation record (key and episodes) of one method x tag x suite."""
        return self.out / "evals" / method / f"seed{tag}" / f"{suite}.json"

    @property
    def cli_check(self) -> Path:
        """The ``lerobot-eval`` cross-check's output folder."""
        return self.out / "lerobot_eval_cli" / "nominal"

    @property
    def figures(self) -> Path:
        return self.out / "figures"

    def figure(self, name: str) -> Path:
        return self.figures / name

    @property
    def report(self) -> Path:
        return self.out / "report.md"

    @property
    def summary(self) -> Path:
        return self.out / "summary.json"

    @property
    def cluster(self) -> Path:
        return self.out / CLUSTER_DIR

    def stage_names(self) -> tuple[str, ...]:
        """The top-level entries the stages write (claimed in the manifest before they run)."""
        return (self.config.name, self.dataset().name, "train", "evals", self.cli_check.parent.name)

    def report_names(self) -> tuple[str, ...]:
        """The top-level entries the report stage writes."""
        return (self.report.name, self.summary.name, self.figures.name)

    def names(self, recordings: list[str], cluster: bool) -> tuple[str, ...]:
        """Every top-level entry a study writes: its stages', the datasets of its other ``recordings``, the cluster
        jobs' folder (with ``cluster``) and the report's."""
        others = tuple(self.dataset(r).name for r in recordings if r != "keyframe")
        return tuple(dict.fromkeys((*self.stage_names(), *others, *self.report_names(), *(CLUSTER_DIR,) * cluster)))
