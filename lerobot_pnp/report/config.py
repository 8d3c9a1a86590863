"""The study's configuration: ``StudyConfig`` (the ``lerobot-pnp report`` / ``demo`` flags) and its presets.

Presets (``preset``): ``demo`` (the README's main command), ``quick`` (CI-sized, a few minutes), ``full``
(the whole study; its timings are in its ``summary.json``, ``docs/results/study/``), all on the paper's task, and
``heldout`` (the held-out-disturbance protocol of ``docs/benchmark/heldout.md``: trained on the ``full``
task, evaluated on its training conditions and beyond them, per axis of ``suites.HELD_OUT_AXES``) with its cut
``recovery_demo`` (one seed, four suites: ``make demo``'s recovery headline). Fields left at None take the
preset's value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from lerobot_pnp.errors import ConfigError
from lerobot_pnp.presets import PRESETS as TASK_PRESETS
from lerobot_pnp.report.episode_rule import EpisodeRule, RuleChanges, resolve_rule
from lerobot_pnp.report.methods import DATA_EFFICIENCY_METHODS, METHODS, RECOVERING_STUDY_SETTINGS, get_methods
from lerobot_pnp.report.slurm import StudySlurmOptions, checked
from lerobot_pnp.sim.suites import STUDY_SUITES, get_suites


@dataclass
class SuiteSpec:
    name: str  # a suite of suites.SUITES, or a sweep group ("nudge")
    n_episodes: int = 200


# Episode counts: the 95 % Wilson half-width is <= 4.4 pts at n = 500, <= 7 pts at n = 200 and <= 10 pts at
# n = 100 (worst case, p = 0.5); near 0 or 100 % it is far smaller (n = 100, 98 %: [93.0, 99.4]). A learned
# method pools 3 training seeds (3 n episodes). The demo's headline gets 200 per seed (600 pooled: [99.4, 100]
# at 100 %; the recovery demo's baselines run under the rule below, as in ``heldout``). The full study gives
# 300 to nominal and 100 to each other suite: enough to separate 50 % from 80 %, or 100 % from 90 %, on the
# paired test. Its stage timings: ``timings_s`` in docs/results/study/report_full/summary.json.
# ``heldout`` chooses its counts from the interval widths its cells need. A cell pools a learned method's seeds,
# so its suites' n is split over the training seeds (``split_over_seeds``: 200 -> 100 per seed, whole eval
# batches, 300 pooled: +-3.4 pts at 90 %, +-2 pts near 97 %, what the claims' bars of 90 / 95 / 98 % need);
# the expert (no seeds) runs 200. The baselines run under ``EpisodeRule``: +-17 pts per evaluation, about
# +-10 pts on a cell pooled over three seeds, so 50 episodes per seed (150 pooled); the lookup table (near 0 %,
# [0, 7] pts at 0 of 50) too. ``full`` keeps fixed counts for its paired comparisons' methods and runs the
# others under a +-10 pts rule (docs/guides/evaluation.md, statistics).
PRESETS: dict[str, dict] = {
    "demo": {
        "num_episodes": 1400,
        "epochs": 300,
        "train_seeds": [1000, 1001, 1002],
        "methods": ["expert", "lookup_table", "clocked_lstm"],
        "suites": [SuiteSpec("nominal", 200), SuiteSpec("nudge_0.03", 200)],
        "data_efficiency": [],
        "cli_check_episodes": 50,
    },
    "quick": {
        "num_episodes": 300,
        "epochs": 150,
        "train_seeds": [1000],
        "methods": ["lookup_table", "clocked_lstm"],
        "suites": [SuiteSpec("nominal", 100), SuiteSpec("nudge_0.03", 100)],
        "data_efficiency": [],
        "cli_check_episodes": 0,
    },
    "full": {
        "num_episodes": 1400,
        "epochs": 300,
        "train_seeds": [1000, 1001, 1002],
        # the costliest: act (its dense recording once, then training and dense evaluation per seed) and
        # recovering_dagger / recovering_dart (rollouts and retraining per seed); timings in
        # docs/results/study/report_full/summary.json
        "methods": [
            "expert",
            "lookup_table",
            "clocked_lstm",
            "shared_lstm",
            "memoryless",
            "memoryless_mlp",
            "phase_told_mlp",
            "recovering",
            "recovering_dagger",
            "recovering_dart",
            "act",
        ],
        "suites": [SuiteSpec(name, 300 if name == "nominal" else 100) for name in STUDY_SUITES["full"]],
        "data_efficiency": [10, 30, 100, 300, 1120],  # 1120 = the whole training split
        "cli_check_episodes": 200,
        # the recipe's second LSTM layer carries two steps of latency on `full`; on the paper task, where no
        # suite is more than one step late and no demonstration moves the cube, it costs the large nudges
        # (docs/changelog.md) and doubles the recipe's training: one layer here
        "recipe_changes": {"num_layers": 1},
        # counts from the interval widths: the expert and the lookup table (every paired comparison's baseline)
        # and the clocked LSTM (paired with it per seed on every suite) run every suite's n; every other method
        # stops once its interval is +-10 pts (50 episodes per seed near 0 or 100 %, the whole 100 near 50 %):
        # its claims read a rate against 50 % or against another method's interval
        "episodes_rule": EpisodeRule(
            half_width=0.1, block=50, fixed_methods=("expert", "lookup_table", "clocked_lstm")
        ),
    },
    # The held-out-disturbance protocol: demonstrations of the `full` task (wide disturbance
    # distributions, recoveries in the demonstrations), evaluated on nominal and on every suite of every axis
    # (in distribution and held out). 200 episodes per suite, split over the 3 seeds of a learned method (100
    # each, 300 pooled); the counts are explained above PRESETS. The clocked planners cannot train on this data (see methods.py), nor can the
    # data-efficiency runs (clocked) or the study's DAgger round (set up for the paper task). The memoryless
    # control runs in the paper-task study (`full`), where it shows what memory adds; here it would score near 0 %
    # in distribution, which gives it no held-out verdict, at the cost of three trainings.
    "heldout": {
        "task_preset": "full",
        "num_episodes": 1000,
        "epochs": 300,
        "train_seeds": [1000, 1001, 1002],
        "methods": ["expert", "lookup_table", "recovering", "act"],
        "suites": [SuiteSpec(name, 200) for name in STUDY_SUITES["heldout"]],
        "data_efficiency": [],
        "cli_check_episodes": 100,
        "split_over_seeds": True,
        # the expert's >= 99 % on every suite is the benchmark's (benchmarks/bench_expert.py, >= 200 each):
        # here it is a reference column, under the baselines' rule; the recovering planner is the claims' method
        "episodes_rule": EpisodeRule(
            half_width=0.17, block=50, fixed_methods=(), claim_methods=("recovering",), claim_half_width=0.045
        ),
    },
    # make demo's second half, the recovery headline: the `heldout` study cut to one training seed and four
    # suites (nominal; a drop in every episode, as trained; drops twice as far, and observations two steps old,
    # neither ever trained): the smallest run that shows the headline; make demo's time is in the README.
    "recovery_demo": {
        "task_preset": "full",
        "num_episodes": 1000,
        "epochs": 300,
        "train_seeds": [1000],
        "methods": ["expert", "lookup_table", "recovering"],
        "suites": [
            SuiteSpec("nominal", 200),
            SuiteSpec("train_drop", 200),
            SuiteSpec("heldout_far_drop", 200),
            SuiteSpec("heldout_latency_2", 200),
        ],
        "data_efficiency": [],
        "cli_check_episodes": 0,
        # the lookup table (0 % on `full`) stops at 50 episodes as in `heldout`; the planner and expert run 200
        "episodes_rule": EpisodeRule(half_width=0.17, block=50, fixed_methods=("expert", "recovering")),
    },
}


@dataclass
class StudyConfig:
    """``lerobot-pnp demo`` / ``lerobot-pnp report``: the study (see the module doc for the presets)."""

    output_dir: str = "outputs/demo"  # everything the study writes (datasets, checkpoints, report.md); resumable
    # the study: demo (the README's main run), quick (CI-sized), full (the whole study), heldout (the held-out
    # protocol) or recovery_demo (make demo's recovery headline)
    preset: str = "demo"
    quick: bool = False  # shorthand for preset=quick
    full: bool = False  # shorthand for preset=full
    num_episodes: int | None = None  # demonstrations generated (80 % train / 20 % held out)
    dataset_seed: int = 0  # seed of the first demonstration (episode i uses dataset_seed + i)
    # the task the demonstrations are generated on (presets.PRESETS: paper or full); None = the preset's, else
    # paper. Every suite applies its changes to this task (as recorded with the data)
    task_preset: str | None = None
    # processes for generation and for the train-and-evaluate jobs (each single-threaded); 0 = one per core
    workers: int = 0
    epochs: int | None = None  # training epochs of each learned method that trains by epochs
    train_seeds: list[int] | None = None  # one training (and evaluation) per learned method and seed
    methods: list[str] | None = None  # methods compared (methods.METHODS), e.g. '["lookup_table", "clocked_lstm"]'
    # evaluation suites and episodes of each, e.g. '[{"name": "nominal", "n_episodes": 100}]'; a group name: its sweep
    suites: list[SuiteSpec] | None = None
    data_efficiency: list[int] | None = None  # numbers of training demonstrations (clocked LSTM vs lookup)
    # episodes of the nominal suite re-run through the real `lerobot-eval` CLI (first learned method, first
    # seed) to show the in-process evaluation gives the same per-episode successes; 0 = skip
    cli_check_episodes: int | None = None
    eval_seed: int = 100_000  # first evaluation seed (disjoint from the dataset's seeds 0..)
    eval_batch_size: int = 50  # sub-envs of the SyncVectorEnv
    # episode counts chosen from the interval widths (EpisodeRule), e.g. '{"half_width": 0.2}' or --episodes_rule.block
    # 100: the fields given change the preset's rule, the others keep its values; None = the preset's (heldout: on;
    # others: off, every suite's n)
    episodes_rule: RuleChanges | None = None
    # each training seed of a learned method runs n / seeds of a suite's episodes (whole eval batches), so its
    # pooled cell holds about n; None = the preset's (heldout: on; others: off, n per seed)
    split_over_seeds: bool | None = None
    fixed_episodes: bool = False  # every evaluation runs its suite's whole n (turns the preset's episodes_rule off)
    act_steps: int | None = None  # ACT training steps per seed (None = act_baseline.ActBudget's default)
    # PnpLstmConfig fields changed in the recovering recipe for every method that takes it (the planner, its
    # DAgger/DART rounds, the matched MLPs), e.g. '{"num_layers": 1}'; None = the preset's (full: one LSTM layer)
    recipe_changes: dict | None = None
    fresh: bool = False  # delete what the study wrote in output_dir first (its manifest); the user's files stay
    report_only: bool = False  # write the report from the finished evaluations only (train/evaluate nothing)
    # config files of other studies run in the same process pool, each with its own output_dir and report:
    # their jobs fill the cores this study's leave idle; --fresh and --report_only apply to them too
    alongside: list[str] = field(default_factory=list)
    # where the datasets, trainings and evaluations run: local (this machine's process pool) or slurm (cluster jobs,
    # --slurm.*; --workers then caps the jobs of one array running at once, 0 = no cap); the same stages and results
    executor: str = "local"
    slurm: StudySlurmOptions = field(default_factory=StudySlurmOptions)

    def __post_init__(self):
        self.executor, self.slurm = checked(self.executor, self.slurm)
        if self.quick and self.full:
            raise ConfigError("pass either --quick or --full, not both")
        self.preset = "quick" if self.quick else "full" if self.full else self.preset
        if self.preset not in PRESETS:
            raise ConfigError(f"preset must be one of {sorted(PRESETS)}, got {self.preset!r}")
        for key, value in PRESETS[self.preset].items():
            if getattr(self, key) is None:
                setattr(self, key, value)
        self.split_over_seeds = bool(self.split_over_seeds)
        self._check_recipe_changes()
        self.task_preset = self.task_preset or "paper"
        if self.task_preset not in TASK_PRESETS:
            raise ConfigError(f"task_preset must be one of {sorted(TASK_PRESETS)}, got {self.task_preset!r}")
        self.suites = [SuiteSpec(**s) if isinstance(s, dict) else s for s in self.suites]
        if self.num_episodes < 10:
            raise ConfigError(f"num_episodes must be >= 10 for an 80/20 split, got {self.num_episodes}")
        if self.epochs < 1 or not self.train_seeds:
            raise ConfigError("epochs must be >= 1 and train_seeds non-empty")
        if any(s.n_episodes < 1 for s in self.suites):
            raise ConfigError("every suite needs n_episodes >= 1")
        if not (isinstance(self.workers, int) and self.workers >= 0):
            raise ConfigError(f"workers must be an integer >= 0 (0 = one per core), got {self.workers!r}")
        batch = self.eval_batch_size
        if not (isinstance(batch, int) and not isinstance(batch, bool) and batch >= 1):
            raise ConfigError(f"eval_batch_size must be an integer >= 1 (sub-envs evaluated at a time), got {batch!r}")
        get_methods(self.methods)  # unknown names fail now, not after an hour
        self._check_rule()
        get_suites([s.name for s in self.suites])
        self._check_task()

    def seed_episodes(self, n_episodes: int) -> int:
        """Episodes of one training seed's evaluation of a suite of ``n_episodes`` (``split_over_seeds``): n
        split over the seeds, rounded up to whole eval batches (a batch's episodes depend on its size)."""
        if not self.split_over_seeds:
            return n_episodes
        share = math.ceil(n_episodes / len(self.train_seeds))
        batch = self.eval_batch_size
        return share if share <= batch else math.ceil(share / batch) * batch

    def _check_rule(self) -> None:
        rule = self.episodes_rule = resolve_rule(self.episodes_rule, PRESETS[self.preset].get("episodes_rule"))
        if self.fixed_episodes:
            rule = self.episodes_rule = None
        if rule is None:
            return
        rule.check(self.eval_batch_size)
        for name in ("fixed_methods", "claim_methods"):
            unknown = [m for m in getattr(rule, name) if m not in METHODS]
            if unknown:
                raise ConfigError(f"episodes_rule.{name}: unknown method(s) {unknown}; valid: {sorted(METHODS)}")

    def _check_recipe_changes(self) -> None:
        from lerobot_pnp.policy import PnpLstmConfig

        self.recipe_changes = dict(self.recipe_changes or {})
        from lerobot.configs.policies import PreTrainedConfig

        # the planner's own fields, not LeRobot's base ones (features, device, hub settings)
        valid = {f.name for f in fields(PnpLstmConfig) if f.init} - {f.name for f in fields(PreTrainedConfig)}
        frozen = {"mode", "max_episode_length", "recurrent"}  # what makes a method what it is, or the task's window
        unknown = sorted(set(self.recipe_changes) - valid)
        if unknown:
            raise ConfigError(f"recipe_changes: unknown pnp_lstm field(s) {unknown}; valid: {sorted(valid - frozen)}")
        if fixed := sorted(set(self.recipe_changes) & frozen):
            raise ConfigError(f"recipe_changes may not set {fixed}: each method and the task decide them")
        # a value the planner refuses fails now, in one line, not after the demonstrations were generated
        try:
            PnpLstmConfig(**{**RECOVERING_STUDY_SETTINGS, **self.recipe_changes})
        except (ValueError, TypeError) as e:
            raise ConfigError(f"recipe_changes {self.recipe_changes}: {e}") from None

    def _check_task(self) -> None:
        """A method that cannot train on the task's demonstrations fails now, in one line, not after an hour."""
        names = list(self.methods) + (list(DATA_EFFICIENCY_METHODS) if self.data_efficiency else [])
        refused: dict[str, list[str]] = {}  # why -> the methods refused for it
        for m in get_methods(list(dict.fromkeys(names))):
            if m.tasks is not None and self.task_preset not in m.tasks:
                where = "" if m.name in self.methods else " (data_efficiency)"
                refused.setdefault(m.tasks_why, []).append(f"{m.name!r}{where}")
        if refused:
            raise ConfigError(
                f"methods that cannot train on the {self.task_preset!r} task: "
                + "; ".join(f"{', '.join(ms)}: {why}" for why, ms in refused.items())
            )
