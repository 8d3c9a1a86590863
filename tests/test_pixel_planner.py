"""The camera-only planner and what its cameras render.

Render settings: ``render_effects`` is part of the recorded observation setup (new tasks render without shadows,
reflections and multisampling; a task recorded before the field existed reads back as rendered with them), and the
two settings render different, deterministic images of the same scene.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lerobot_pnp.env_config import BaxterPnPEnvConfig, make_env
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.recorded_task import RECORDED_FILE, write_recorded


# ---------------------------------------------------------------------------------------------- render settings
def test_render_effects_off_by_default_and_recorded(tmp_path):
    assert BaxterPnPEnvConfig().render_effects is False
    write_recorded(BaxterPnPEnvConfig(cameras=["front"], image_height=32, image_width=32), tmp_path)
    assert json.loads((tmp_path / RECORDED_FILE).read_text())["render_effects"] is False
    assert BaxterPnPEnvConfig(task_source=str(tmp_path)).render_effects is False
    assert BaxterPnPEnvConfig(task_source=str(tmp_path), render_effects=True).render_effects is True  # flag wins


def test_a_task_recorded_before_the_field_reads_back_with_effects(tmp_path):
    """The recorded-task rule: a field missing from a stored config has the value it had then."""
    write_recorded(BaxterPnPEnvConfig(cameras=["front"], image_height=32, image_width=32), tmp_path)
    path = tmp_path / RECORDED_FILE
    old = json.loads(path.read_text())
    del old["render_effects"]
    path.write_text(json.dumps(old))
    cfg = BaxterPnPEnvConfig(task_source=str(tmp_path))
    assert cfg.render_effects is True and cfg.cameras == ["front"]
    from lerobot_pnp.cache import same_env_configs

    assert same_env_configs(old, cfg.to_dict())  # a stored stage of that task is the same task
    assert not same_env_configs(old, BaxterPnPEnvConfig(cameras=["front"], image_height=32, image_width=32).to_dict())


def test_render_effects_must_be_a_bool():
    with pytest.raises(ConfigError, match="render_effects must be true or false"):
        BaxterPnPEnvConfig(render_effects="yes")


def test_the_two_settings_render_different_deterministic_images():
    images = {}
    for effects in (True, False):
        env = make_env(cameras=["front"], image_height=32, image_width=32, render_effects=effects, render_mode=None)
        first = env.reset(seed=3)[0]["pixels"]["front"]
        again = env.unwrapped.physics.render("front", 32, 32, effects)
        assert np.array_equal(first, again) and first.std() > 0
        images[effects] = first
        env.close()
    assert not np.array_equal(images[True], images[False])
    # the scene is the same: the images differ in shading, not in what is where
    assert np.abs(images[True].astype(int) - images[False].astype(int)).mean() < 40
