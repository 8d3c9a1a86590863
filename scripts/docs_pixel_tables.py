"""The camera planner page's tables (docs/results/pixel_planner.md), generated from its committed records.

``scripts/docs_tables.py`` owns the page's generated blocks; this module holds the blocks of that one page: the
runs of ``benchmarks/pixel_planner.py`` (one catalogue, ``RUNS`` of ``benchmarks/pixel_planner_plot.py``, which
also draws the curve), what their keypoints know, how their episodes fail, and the 3-seed protocols pooled by
``lerobot-pnp compare``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
sys.path.insert(0, str(ROOT / "benchmarks"))
from pixel_planner_plot import RUNS, checkpoints  # noqa: E402

from lerobot_pnp.evaluation.compare import difference_text  # noqa: E402

TRAIN_SUITES = ("nominal", "train_grasp_miss", "train_drop", "train_displace", "train_nudge", "train_latency",
                "train_mixture")  # fmt: skip
CAUSES = ("not_grasped", "dropped", "not_transported", "not_placed", "not_released")
# the protocols on the page, newest first: (folder under docs/results/, its demonstrations, what sets it apart,
# its state planner's data)
PROTOCOLS = (
    ("pixel_protocol_pose", 7200, "7200 demonstrations", "same data"),
    ("pixel_protocol_strength", 7200, "7200 demonstrations, pose loss weight 0.1", "same data"),
    ("pixel_protocol_7200", 7200, "7200 demonstrations, keypoint positions only", "3600 of these demonstrations"),
    ("pixel_protocol_3600", 3600, "3600 demonstrations, positions only", "same data"),
    ("pixel_protocol", 1200, "1200 demonstrations, positions only", "same data"),
)


def _record(name: str) -> dict:
    return json.loads((RESULTS / name).read_text())


def _minutes(seconds: float) -> str:
    m = seconds / 60
    return f"{m:.1f}" if m < 10 else f"{m:.0f}"


def _pct(rate: float) -> str:
    return f"{100 * rate:.1f}".removesuffix(".0")


def _rate(cell: dict) -> str:
    lo, hi = cell["interval"]
    return f"{_pct(cell['rate'])} % [{100 * lo:.1f}, {100 * hi:.1f}]"


def _per_seed(cell: dict) -> str:
    """A pooled cell's per-training-seed rates, in the order of its runs: "93, 95, 69"."""
    return ", ".join(_pct(r) for r in cell["per_seed"])


def _checkpoint_rate(row: dict) -> str:
    """One checkpoint's nominal success with its 95 % Wilson interval (a ``pixel_planner.nominal_row``)."""
    lo, hi = row["wilson95_pct"]
    return f"{row['success_pct']:g} % [{lo}, {hi}]"


def _curve(rows: list[dict], steps: bool = False) -> str:
    """Each checkpoint's training time (and step) and nominal success, the last with its interval."""
    cells = []
    for i, row in enumerate(rows):
        step = f" (step {row['step']})" if steps else ""
        rate = _checkpoint_rate(row) if i == len(rows) - 1 else f"{row['success_pct']:g} %"
        cells.append(f"{_minutes(row['train_time_s'])} min{step}: {rate}")
    return ", ".join(cells)


def runs_table(base: str) -> str:
    """One row per run: its data, encoder input and steps, each checkpoint's time and nominal success."""
    lines = [
        "| demonstrations | encoder input | steps | checkpoints: training time -> nominal success | held-out loss at the end | record |",
        "|---|---|---|---|---|---|",
    ]  # fmt: skip
    for run in RUNS:
        rec = _record(run.record)
        rows = checkpoints(rec)
        mse = (rec.get("train_summary") or {}).get("final_test_mse", rows[-1].get("test_mse"))
        name = run.record.rsplit("/", 1)[-1]
        lines.append(f"| {run.demos} | {run.encoder} | {run.steps}{run.note} | {_curve(rows)} | {mse:.3f} | "
                     f"[{name}]({base}{run.record}) |")  # fmt: skip
    return "\n".join(lines)


def _measured(key: str) -> list[tuple]:
    """``(run, record[key])`` of each run whose record measured ``key``."""
    records = [(run, _record(run.record)) for run in RUNS]
    return [(run, rec[key]) for run, rec in records if rec.get(key)]


def _protocols() -> list[tuple[str, int, str, str]]:
    """The protocols of ``PROTOCOLS`` whose comparison is committed, newest first."""
    return [p for p in PROTOCOLS if (RESULTS / p[0] / "compare" / "compare.json").is_file()]


def pose_table(base: str) -> str:
    """The auxiliary head's mean absolute error on the held-out episodes, every frame and the first."""
    lines = [
        "| demonstrations, encoder input, steps | cube x | cube y | yaw (sin 4x) | target x | target y | first frame: cube x | cube y | yaw (sin 4x) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]  # fmt: skip
    for run, pose in _measured("pose_error"):
        a, f = pose["all_frames"], pose["first_frame"]
        cm = [f"{100 * v:.1f} cm" for v in (a["object_x"], a["object_y"])]
        goal = [f"{100 * v:.1f} cm" for v in (a["goal_x"], a["goal_y"])]
        first = [f"{100 * v:.1f} cm" for v in (f["object_x"], f["object_y"])]
        lines.append(f"| {run.label} | {' | '.join(cm)} | {a['object_yaw_sin4']:.2f} | {' | '.join(goal)} | "
                     f"{' | '.join(first)} | {f['object_yaw_sin4']:.2f} |")  # fmt: skip
    return "\n".join(lines)


def failures_table(base: str) -> str:
    """Each run's last checkpoint's nominal episodes by failure cause, and the 300-demonstration state planner."""
    lines = ["| checkpoint | successes | " + " | ".join(f"`{c}`" for c in CAUSES) + " |", "|---|---" + "|---" * 5 + "|"]
    rows = [(f"camera planner, {run.label}", fails) for run, fails in _measured("failures")]
    state = _record("pixel_baselines/baselines.json")["state_planner"]["failures"]
    for label, fails in [*rows, ("state planner, 300 demonstrations, 800 steps", state)]:
        counts = " | ".join(str(fails["by_cause"].get(c, 0)) for c in CAUSES)
        lines.append(f"| {label} | {fails['successes']} / {fails['n']} | {counts} |")
    return "\n".join(lines)


def _agreement(test: dict) -> str:
    """A ``lerobot-pnp compare`` seed-homogeneity test as a cell: "no (0.7)", "yes (2e-15)"."""
    return f"{'yes' if test['differ'] else 'no'} ({test['p']:.1g})"


def protocol_table(base: str) -> str:
    """The newest protocol's camera planner pooled over its seeds and per seed, the state planner on the same data,
    and the camera planner of each earlier protocol."""
    (folder, _, _, state_data), *earlier = _protocols()
    compared = _record(f"{folder}/compare/compare.json")
    new = compared["success"]
    seeds = ", ".join(path.rsplit("seed", 1)[-1] for path in compared["runs"]["camera_planner"])
    old = [(label, _record(f"{f}/compare/compare.json")["success"]) for f, _, label, _ in earlier]
    cam, state = new["nominal"]["camera_planner"], new["nominal"]["state_planner"]
    head = [f"camera planner, {len(cam['per_seed'])} seeds pooled (n = {cam['n']})", f"per seed ({seeds})",
            "seeds differ? (p)", f"state planner, {state_data} (n = {state['n']})"]  # fmt: skip
    head += [f"camera planner, {label} (n = {s['nominal']['camera_planner']['n']})" for label, s in old]
    lines = ["| suite | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
    for suite in TRAIN_SUITES:
        c = new[suite]["camera_planner"]
        cells = [
            _rate(c),
            _per_seed(c) + " %",
            _agreement(compared["seeds"]["camera_planner"][suite]),
            _rate(new[suite]["state_planner"]),
            *(_rate(s[suite]["camera_planner"]) for _, s in old),
        ]
        lines.append(f"| `{suite}` | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def joints_table(base: str) -> str:
    """Each run's held-out next-keyframe error per joint (mean absolute and RMS, degrees): where the camera
    planner's actions are off, beside the state planner's."""
    runs = _record("pixel_keyframe_error.json")["runs"]
    joints = list(next(iter(runs.values()))["per_joint_mae_deg"])
    lines = ["| run | " + " | ".join(f"`{j}`" for j in joints) + " |", "|---" * (len(joints) + 1) + "|"]
    for label, rec in runs.items():
        mae, rmse = rec["per_joint_mae_deg"], rec["per_joint_rmse_deg"]
        lines.append(f"| {label} | " + " | ".join(f"{mae[j]:.2f} / {rmse[j]:.1f}" for j in joints) + " |")
    return "\n".join(lines)


def heldout_table(base: str) -> str:
    """The leaderboard row's held-out axes: in distribution against held out, with the study's verdict."""
    from lerobot_pnp.evaluation.leaderboard import analyse_rows

    _, _, axes = analyse_rows(RESULTS / "leaderboard")
    lines = ["| axis | in distribution | held out | verdict |", "|---|---|---|---|"]
    for (axis, row), result in axes.items():
        if row == "pnp_pixels":
            inside, outside = _pct(result.inside.rate), _pct(result.outside.rate)
            lines.append(f"| {axis} | {inside} % | {outside} % | {result.judged.phrase()} |")
    return "\n".join(lines)


def headline(base: str) -> str:
    """The newest protocol's pooled nominal rate beside its state planner's, for the results overview."""
    folder, demos, _, _ = _protocols()[0]
    nominal = _record(f"{folder}/compare/compare.json")["success"]["nominal"]
    cam, state = nominal["camera_planner"], nominal["state_planner"]
    wins = round(state["rate"] * state["n"])
    return (
        f"Trained from {demos} demonstrations (three seeds of 9000 steps; their training times: the camera planner page), it succeeds on {_rate(cam)} of nominal "
        f"episodes ({len(cam['per_seed'])} seeds, {cam['n']} episodes), where the state planner succeeds on {wins} of "
        f"{state['n']}: [its results, baselines and what limits it]({base}pixel_planner.md)."
    )


def _act_row(name: str, data: str) -> str:
    """Image ACT at each evaluated checkpoint of one ``benchmarks/image_act_budget.py`` record."""
    rec = _record(f"pixel_baselines/{name}")
    threads = rec.get("threads", 1)
    budget = f"{threads} torch thread{'s' * (threads > 1)} for {_minutes(rec['budget_s'])} minutes of training"
    return f"| image ACT | {data}; {budget}, batch 16 | {_curve(rec['nominal'], steps=True)} |"


def _pair(compared: dict, run: str, reference: str, suite: str) -> dict:
    """``run`` minus ``reference`` on ``suite`` (same eval seeds) in one ``lerobot-pnp compare`` record."""
    return next(p for p in compared["pairs"] if (p["run"], p["reference"], p["suite"]) == (run, reference, suite))


def _paired(pair: dict) -> str:
    """A pair's difference with its interval and the largest per-seed p."""
    return f"{difference_text(pair)}, p <= {pair['study']['max_p']:.1g}"


def baselines_table(base: str) -> str:
    """Every baseline's nominal success on the data of a camera planner run, beside that run where they pair."""
    lines = ["| baseline | data and budget | nominal success [95 % Wilson] |", "|---|---|---|"]
    lines.append(_act_row("image_act.json", "1200 demonstrations"))
    lines.append(_act_row("image_act_7200.json", "7200 demonstrations (the recipe's)"))
    small = _record("pixel_baselines/compare/compare.json")
    rates = small["success"]["baxter_pnp"]
    pair = _paired(_pair(small, "pixels_memoryless", "pixels_recurrent", "baxter_pnp"))
    lines.append(f"| memoryless control | 300 demonstrations, 800 steps | {_rate(rates['pixels_memoryless'])}; the "
                 f"camera planner {_rate(rates['pixels_recurrent'])} on the same data and steps ({pair}) |")  # fmt: skip
    big = _record("pixel_protocol_memoryless/compare/compare.json")
    ml, cam = big["success"]["nominal"]["memoryless"], big["success"]["nominal"]["camera_planner"]
    pair = _paired(_pair(big, "memoryless", "camera_planner", "nominal"))
    lines.append(f"| memoryless control | 7200 demonstrations, the recipe's 9000 steps, {len(ml['per_seed'])} seeds | "
                 f"{_rate(ml)} (per seed {_per_seed(ml)} %); the camera planner "
                 f"{_rate(cam)} ({pair}) |")  # fmt: skip
    state = "| state planner (reads the environment state) | {} ({:.0f} s of training) | {} |"
    last = _record("pixel_baselines/baselines.json")["state_planner"]["nominal"][-1]
    lines.append(state.format("300 demonstrations, 800 steps", last["train_time_s"], _checkpoint_rate(last)))
    for folder, data in (("pixel_protocol", "1200 demonstrations, 2000 steps"),
                         ("pixel_protocol_3600", "3600 demonstrations, 6000 steps"),
                         ("pixel_protocol_strength", "7200 demonstrations, 9000 steps")):  # fmt: skip
        rate = _rate(_record(f"{folder}/compare/compare.json")["success"]["nominal"]["state_planner"])
        seconds = _record(f"{folder}/protocol.json")["train"]["state_planner"]["train_time_s"]
        lines.append(state.format(data, seconds, rate))
    return "\n".join(lines)


def memoryless_table(base: str) -> str:
    """The memoryless control beside the camera planner it ablates (``pixel_protocol_strength``'s, pose weight
    0.1), per suite, pooled over the same training and eval seeds."""
    compared = _record("pixel_protocol_memoryless/compare/compare.json")
    nominal = compared["success"]["nominal"]
    head = [f"camera planner, pose weight 0.1 (n = {nominal['camera_planner']['n']})", f"memoryless control (n = {nominal['memoryless']['n']})",
            "per seed", "memoryless minus camera planner, paired", "verdict"]  # fmt: skip
    lines = ["| suite | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
    for suite, cell in compared["success"].items():
        ml = cell["memoryless"]
        pair = _pair(compared, "memoryless", "camera_planner", suite)
        lines.append(f"| `{suite}` | {_rate(cell['camera_planner'])} | {_rate(ml)} | "
                     f"{_per_seed(ml)} % | {_paired(pair)} | {pair['verdict']} |")  # fmt: skip
    return "\n".join(lines)


def memoryless_training(base: str) -> str:
    """Per training seed: each method's wall clock and held-out next-keyframe error (its ``protocol.json``)."""
    recipe = _record("pixel_protocol_strength/protocol.json")["train"]
    memoryless = _record("pixel_protocol_memoryless/protocol.json")["train"]
    lines = ["| training seed | camera planner, pose weight 0.1: training wall clock | its next-keyframe error | memoryless control: "
             "training wall clock | its next-keyframe error |", "|---|---|---|---|---|"]  # fmt: skip
    for name, ml in memoryless.items():
        seed = name.removeprefix("memoryless_seed")
        cam = recipe[f"camera_seed{seed}"]
        lines.append(f"| {seed} | {_minutes(cam['wall_s'])} min | {cam['keyframe_mae_deg']:.2f}° | "
                     f"{_minutes(ml['wall_s'])} min | {ml['keyframe_mae_deg']:.2f}° |")  # fmt: skip
    return "\n".join(lines)


def _lever_table(compared: dict, study: dict, reference: str, label, runs_of, name, note: str) -> str:
    """A lever's runs beside a reference run (``reference``) on the same training and eval seeds, per suite, from
    a ``lerobot-pnp compare`` record and the lever's training records by training name (``study``).
    ``label(run)`` names a compared run in the header, ``note`` says what the reference is, ``runs_of(seeds,
    recipe)`` gives the reference's training records by training name from ``pixel_protocol_strength``'s, and
    ``name(training)`` names a training in the losses line."""
    others = [run for run in compared["runs"] if run != reference]
    seeds = sorted({name.split("seed")[1] for name in study})
    n = compared["success"]["nominal"][reference]["n"]
    head = [f"{label(reference)}, {note}, pooled (n = {n}; seeds {', '.join(seeds)})"]
    for run in others:
        head += [label(run), f"{label(run)} minus {label(reference)}, paired", "verdict"]
    lines = ["| suite | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
    for suite, cell in compared["success"].items():
        row = [_rate(cell[reference]) + f" ({_per_seed(cell[reference])})"]
        for run in others:
            pair = _pair(compared, run, reference, suite)
            row += [_rate(cell[run]) + f" ({_per_seed(cell[run])})", _paired(pair),
                    pair["verdict"]]  # fmt: skip
        lines.append(f"| `{suite}` | " + " | ".join(row) + " |")
    recipe = _record("pixel_protocol_strength/protocol.json")["train"]
    runs = runs_of(seeds, recipe) | study
    mse = "; ".join(
        f"{name(k)}: {r['final_train_mse']:.3f} / {r['final_test_mse']:.3f} / {r['keyframe_mae_deg']:.2f}°"
        for k, r in runs.items()
    )
    return (
        "\n".join(lines) + "\n\nThe last epoch's training loss (on augmented batches) / the held-out action MSE / "
        f"the held-out mean next-keyframe error per arm joint: {mse}."
    )


def _screen(folder: str) -> tuple[dict, dict]:
    """A two-seed lever screen's ``lerobot-pnp compare`` record and training records."""
    return _record(f"{folder}/compare/compare.json"), _record(f"{folder}/study.json")["train"]


def _shift_name(name: str) -> str:
    """``shift0_seed1000`` -> "0 px, seed 1000"."""
    return f"{name.split('_')[0].removeprefix('shift')} px, seed {name.split('seed')[1]}"


def shift_table(base: str) -> str:
    """Each random shift beside the recipe's (``shift_4``) on the same training and eval seeds, per suite."""
    return _lever_table(
        *_screen("pixel_shift"),
        "shift_4",
        lambda run: f"shift {run.removeprefix('shift_')} px",
        lambda seeds, recipe: {f"shift4_seed{s}": recipe[f"camera_seed{s}"] for s in seeds},
        _shift_name,
        "the recipe at pose weight 0.1",
    )


def _versus_recipe(
    records: tuple[dict, dict], labels: tuple[str, str], short: tuple[str, str], note: str, reference: str = "recipe"
) -> str:
    """``_lever_table`` of one lever against ``pixel_protocol_strength``'s camera planner, the recipe at pose
    weight 0.1 (compared run ``reference``): ``labels`` name the two in the header, ``short`` in the losses line."""
    return _lever_table(
        *records,
        reference,
        lambda run: labels[0] if run == reference else labels[1],
        lambda seeds, recipe: {f"recipe_seed{s}": recipe[f"camera_seed{s}"] for s in seeds},
        lambda name: f"{short[0] if name.startswith('recipe') else short[1]}, seed {name.split('seed')[1]}",
        note,
    )


def strength_norm_table(base: str) -> str:
    """Batch-normalised keypoint strengths beside the recipe's raw ones, and the raw strengths' scale per camera."""
    table = _versus_recipe(
        _screen("pixel_strength_norm"),
        ("raw strengths", "normalised strengths"),
        ("raw", "normalised"),
        "the recipe at pose weight 0.1",
    )
    study = _record("pixel_strength_norm/study.json")["train"]
    scale = "; ".join(
        f"seed {name.split('seed')[1]}, {cam}: means {r['mean_range'][0]} to {r['mean_range'][1]}, "
        f"standard deviations {r['std_range'][0]} to {r['std_range'][1]}"
        for name, run in study.items()
        for cam, r in run["raw_strength"].items()
    )
    return table + f"\n\nThe strengths before the normalisation, over each camera's 16 keypoints: {scale}."


def pose_weight_table(base: str) -> str:
    """The recipe's pose loss weight (1.0, ``pixel_protocol_pose``) beside 0.1 (``pixel_protocol_strength``), on
    the same three training seeds and the same eval seeds."""
    compared = _record("pixel_protocol_pose/compare_pose_weight/compare.json")
    train = _record("pixel_protocol_pose/protocol.json")["train"]
    lever = {name.replace("camera_", "lever_"): run for name, run in train.items() if name.startswith("camera_")}
    table = _versus_recipe(
        (compared, lever),
        ("pose weight 0.1", "pose weight 1.0"),
        ("0.1", "1.0"),
        "pixel_protocol_strength",
        reference="pose_weight_0.1",
    )
    seeds = "; ".join(
        f"pose weight {run.removeprefix('pose_weight_')}: "
        + ", ".join(f"`{suite}` {a['p']:.1g}" for suite, a in per.items())
        for run, per in compared["seeds"].items()
    )
    return (
        table + " The losses hold the auxiliary pose term at each run's weight: only the next-keyframe error "
        "compares.\n\nDo the three training seeds share one rate? The chi-square test of homogeneity of their "
        f"success counts, p per suite (below 0.05: they differ beyond evaluation noise): {seeds}."
    )


BLOCKS = {
    "pixel-headline": headline,
    "pixel-joints": joints_table,
    "pixel-runs": runs_table,
    "pixel-pose": pose_table,
    "pixel-failures": failures_table,
    "pixel-protocol": protocol_table,
    "pixel-heldout": heldout_table,
    "pixel-baselines": baselines_table,
    "pixel-memoryless": memoryless_table,
    "pixel-memoryless-training": memoryless_training,
    "pixel-shift": shift_table,
    "pixel-strength-norm": strength_norm_table,
    "pixel-pose-weight": pose_weight_table,
}
