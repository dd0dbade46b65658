"""The Gymnasium adapter passes Gymnasium's own environment checker."""

from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium.utils.env_checker import check_env

from efam_mujoco.suite.gym import SuiteEnv, register_all


def test_adapter_passes_gymnasiums_checker():
    env = SuiteEnv("bundle", "reach")
    check_env(env, skip_render_check=True)
    assert env.action_space.low.min() == 0.0 and env.action_space.high.max() == 1.0
    observation, _ = env.reset(seed=3)
    assert observation.shape == env.observation_space.shape == (15,)
    again, _ = env.reset(seed=3)
    np.testing.assert_array_equal(observation, again)
    steps, truncated = 0, False
    while not truncated:
        observation, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert not terminated and 0.0 <= reward <= 1.0 and isinstance(info["success"], bool)
        steps += 1
    assert steps == 100  # 10 s at 10 Hz


def test_registered_ids_make_environments():
    ids = register_all()
    assert "efam/arm-push-v0" in ids and len(ids) == 10
    env = gymnasium.make("efam/bundle-extend-v0")
    observation, _ = env.reset(seed=0)
    assert env.observation_space.contains(observation)
    env.close()
