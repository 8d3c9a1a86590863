"""The visual axes of the held-out protocol (``sim/visual_suites.py``): their suites through stock ``lerobot-eval``'s
``--env.task``, policies that see no pixels unchanged on every one of them, and a verdict per visual axis from
``compare`` and the leaderboard by the one rule of ``evaluation/verdicts.py``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from test_stock_eval_cameras import pixels_checkpoint  # noqa: F401  (a tiny camera checkpoint)

from lerobot_pnp import cli
from lerobot_pnp.evaluation.verdicts import axis_verdict
from lerobot_pnp.presets import VISUAL_TRAINING
from lerobot_pnp.sim import visual
from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
from lerobot_pnp.sim.stock_suites import ALIASES, suite_names, valid_names
from lerobot_pnp.sim.suites import ALL_AXES, HELD_OUT_AXES, PROTOCOL_SUITES, SUITES
from lerobot_pnp.sim.visual_suites import HELD_OUT_RANGES, TRAIN_SUITE, VISUAL_AXES, VISUAL_SUITES


def test_visual_suites_and_axes_in_the_catalogue_and_in_env_task():
    assert suite_names("heldout_visual") == ["nominal", *VISUAL_SUITES] and len(VISUAL_SUITES) == 13
    assert suite_names("heldout") == ["nominal", *PROTOCOL_SUITES] and len(suite_names("heldout")) == 18
    for axis in VISUAL_AXES:
        assert suite_names(f"heldout_{axis.name}") == [TRAIN_SUITE, *axis.held_out]
        assert axis.in_distribution == (TRAIN_SUITE,) and axis in ALL_AXES and axis not in HELD_OUT_AXES
    groups = {s.group for s in SUITES.values() if s.group}
    axis_names = [f"heldout_{a.name}" for a in ALL_AXES]
    assert not set(axis_names) & (set(SUITES) | groups | set(ALIASES)) and len(set(valid_names())) == len(valid_names())
    for name in VISUAL_SUITES:
        (part,) = SUITES[name].parts
        assert set(part) == set(visual.FIELDS)  # every visual field stated: the same on any training task
        beyond = {f for f, v in part.items() if v != VISUAL_TRAINING[f]}
        assert all(part[f] == HELD_OUT_RANGES[f] for f in beyond) and (bool(beyond) == (name != TRAIN_SUITE))


def test_env_task_refuses_an_unknown_visual_name_in_one_line():
    from lerobot_pnp.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        BaxterPnPEnvConfig(preset="full", task="heldout_lighting,heldout_colour")
    assert "unknown suite 'heldout_colour'" in str(err.value) and "heldout_color" in str(err.value)
    assert "\n" not in str(err.value)


def test_the_expert_keeps_every_episode_on_every_visual_suite(tmp_path, capsys):
    """``lerobot-pnp expert --env.task heldout_visual`` (the suites, env configs and seeds of stock lerobot-eval): the
    expert plans from the simulator, so every visual suite's outcomes are nominal's, episode by episode."""
    out = tmp_path / "expert"
    args = ["expert", "--env.preset", "full", "--env.task", "heldout_visual", "--n_episodes", "3", "--seed", "7"]
    assert cli.main([*args, "--progress", "false", "--output_dir", str(out)]) == 0
    capsys.readouterr()
    info = json.loads((out / "eval_info.json").read_text())
    outcomes = {t["task_group"]: t["metrics"]["successes"] for t in info["per_task"]}
    assert list(outcomes) == ["nominal", *VISUAL_SUITES]
    assert all(ok == outcomes["nominal"] for ok in outcomes.values()) and any(outcomes["nominal"]), outcomes


@pytest.fixture(scope="module")
def lookup_checkpoint(tmp_path_factory):
    """The lookup table (a policy of the state: it replays its demonstrations) over `paper` demonstrations of seeds
    100-104 (its training split: four of them)."""
    from lerobot_pnp.dataset import GenerateConfig, generate

    root = tmp_path_factory.mktemp("visual_lookup")
    generate(GenerateConfig(repo_id="local/demos", root=str(root / "demos"), num_episodes=5, seed=100, workers=1,
                            progress=False, env=BaxterPnPEnvConfig(preset="paper")))  # fmt: skip
    assert cli.main(["lookup-table", "--dataset_root", str(root / "demos"), "--output_dir", str(root / "table")]) == 0
    return root / "table"


def test_a_state_policy_through_stock_lerobot_eval_is_the_same_on_visual_suites(lookup_checkpoint):
    """Stock lerobot-eval's loading and multi-suite rollout (``eval_policy_all`` on ``--env.task``): a checkpoint
    that reads the state meets the same episodes, and succeeds on the same ones, on visual suites as on nominal."""
    import torch
    from lerobot.configs import PreTrainedConfig
    from lerobot.envs.factory import make_env_pre_post_processors
    from lerobot.policies.factory import make_policy, make_pre_post_processors
    from lerobot.scripts.lerobot_eval import eval_policy_all

    task = "nominal,train_visual,heldout_more_distractors,heldout_camera_tilt,heldout_image_noise"
    env_cfg = BaxterPnPEnvConfig.from_source(str(lookup_checkpoint), task=task)
    policy_cfg = PreTrainedConfig.from_pretrained(lookup_checkpoint)
    policy_cfg.pretrained_path = lookup_checkpoint
    policy = make_policy(policy_cfg, env_cfg=env_cfg)
    overrides = {"device_processor": {"device": "cpu"}, "rename_observations_processor": {"rename_map": {}}}
    pre, post = make_pre_post_processors(policy_cfg, pretrained_path=str(lookup_checkpoint),
                                         preprocessor_overrides=overrides)  # fmt: skip
    env_pre, env_post = make_env_pre_post_processors(env_cfg, policy_cfg)
    with torch.no_grad():
        info = eval_policy_all(env_cfg.create_envs(n_envs=2), policy, env_pre, env_post, pre, post, 4, start_seed=100)
    outcomes = {t["task_group"]: t["metrics"]["successes"] for t in info["per_task"]}
    assert list(outcomes) == task.split(",")
    assert sum(outcomes["nominal"]) >= 3  # the demonstrations' own seeds: replays of the training split succeed
    assert all(ok == outcomes["nominal"] for ok in outcomes.values()), outcomes


# ------------------------------------------------------------------------------------------------ verdicts
# held-out suite successes out of N per axis, with train_visual at TRAIN_OK / N: each axis a different verdict
N, TRAIN_OK = 400, 396
HELD_OK = {"lighting": 394, "color": 300, "camera": 380, "distractors": 396, "sensor": 360}
EXPECTED = {
    "lighting": "generalises",
    "color": "does_not_generalise",
    "camera": "undecided",
    "distractors": "generalises",
    "sensor": "does_not_generalise",
}


def _visual_run(root: Path, train_ok: int) -> Path:
    from test_compare import eval_info

    held = {s: HELD_OK[a.name] for a in VISUAL_AXES for s in a.held_out}
    outcomes = {s: [i < k for i in range(N)] for s, k in {"nominal": N, TRAIN_SUITE: train_ok, **held}.items()}
    root.mkdir(parents=True)
    (root / "eval_info.json").write_text(json.dumps(eval_info(outcomes)))
    return root


def test_compare_gives_a_verdict_per_visual_axis_by_the_one_rule(tmp_path, capsys):
    good = _visual_run(tmp_path / "good", TRAIN_OK)
    weak = _visual_run(tmp_path / "weak", 300)  # below 90 % in distribution: no verdict on any axis
    out = tmp_path / "compare"
    assert cli.main(["compare", f"cam={good}", f"weak={weak}", "--output_dir", str(out)]) == 0
    capsys.readouterr()
    entries = {(e["axis"], e["method"]): e for e in json.loads((out / "compare.json").read_text())["held_out_axes"]}
    assert {a for a, _ in entries} == {a.name for a in VISUAL_AXES}  # no disturbance axis: its suites are absent
    from lerobot_pnp.evaluation.stats import Rate

    for axis in VISUAL_AXES:
        held = Rate(HELD_OK[axis.name] * len(axis.held_out), N * len(axis.held_out))
        rule = axis_verdict(Rate(TRAIN_OK, N), held)
        assert entries[(axis.name, "cam")]["verdict"] == rule.code == EXPECTED[axis.name], axis.name
        assert entries[(axis.name, "weak")]["verdict"] == "no_verdict"
    page = (out / "compare.md").read_text()
    assert "| color | cam |" in page and "does not generalise" in page and "undecided" in page


def test_the_leaderboard_shows_the_visual_axes_only_for_rows_evaluated_on_them(tmp_path):
    from test_leaderboard import _write_row

    from lerobot_pnp.evaluation.leaderboard import render

    runs = tmp_path / "runs"
    _write_row(runs, "a_state", ok=10, n=N)
    assert "## Visual axes" not in render(runs, n_episodes=N)  # the page as it was without visual rows
    cam = runs / "b_camera"
    _visual_run(cam, TRAIN_OK)
    info = json.loads((cam / "eval_info.json").read_text())
    state = json.loads((runs / "a_state" / "eval_info.json").read_text())
    info["per_task"] = state["per_task"] + [t for t in info["per_task"] if t["task_group"] != "nominal"]
    info["per_group"] = {**state["per_group"], **info["per_group"]}
    (cam / "eval_info.json").write_text(json.dumps(info))
    (cam / "row.json").write_text(json.dumps({"label": "camera policy", "command": "lerobot-eval ..."}))
    page = render(runs, n_episodes=N)
    table = page[page.index("## Visual axes") : page.index("## Per suite")]
    assert "| `b_camera` | camera policy |" in table and "`a_state`" not in table
    assert "99.0 -> 75.0: does not generalise" in table and "99.0 -> 98.5: generalises" in table


@pytest.mark.slow
def test_stock_lerobot_eval_runs_a_visual_axis_on_a_camera_checkpoint_and_compare_judges_it(
    pixels_checkpoint,  # noqa: F811  (the fixture imported above)
    tmp_path,
    capsys,
):
    """``lerobot-eval``'s entry point (in a process forked from a warm interpreter, tests/zygote.py) on a (tiny,
    untrained) camera checkpoint with ``--env.task heldout_sensor``: one entry per suite of the axis, and ``compare``
    gives the axis its verdict (none: far below 90 % in distribution)."""
    from clis import exe
    from zygote import run

    out = tmp_path / "eval"
    args = [exe("lerobot-eval"), f"--policy.path={pixels_checkpoint}", "--env.type=baxter_pnp", "--env.task=heldout_sensor",
            "--eval.n_episodes=2", "--eval.batch_size=2", "--eval.use_async_envs=false", "--policy.device=cpu",
            "--seed=100000", f"--output_dir={out}"]  # fmt: skip
    proc = run(args, tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    info = json.loads((out / "eval_info.json").read_text())
    assert [t["task_group"] for t in info["per_task"]] == suite_names("heldout_sensor")
    assert cli.main(["compare", f"cam={out}", "--output_dir", str(tmp_path / "compare")]) == 0
    capsys.readouterr()
    (entry,) = json.loads((tmp_path / "compare" / "compare.json").read_text())["held_out_axes"]
    assert entry["axis"] == "sensor" and entry["verdict"] == "no_verdict" and entry["held_out"]["n"] == 4
