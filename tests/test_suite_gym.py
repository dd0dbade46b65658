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


def test_adapter_refuses_a_step_after_the_end_and_says_when_it_clips():
    """Stepped after truncation, dm_control reset itself and returned reward None (a TypeError);
    a NaN action raised dm_control's PhysicsError; actions outside [0, 1] were clipped silently."""
    import pytest

    env = SuiteEnv("bundle", "reach", task_kwargs={"time_limit": 0.3})
    env.reset(seed=1)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0.5, 0.5]))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(7))
    with pytest.warns(RuntimeWarning, match="outside \\[0, 1\\]: clipped"):
        env.step(np.array([5.0, 0.5, 0.5]))
    truncated = False
    while not truncated:
        *_, truncated, _ = env.step(env.action_space.sample())
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(env.action_space.sample())
    env.reset()
    env.step(env.action_space.sample())  # a new episode steps again


def test_adapter_refuses_an_image_size_without_pixels():
    import pytest

    for size in [(0, 0), (-240, 320), (240,), "240x320"]:
        with pytest.raises(ValueError, match=r"size"):
            SuiteEnv("bundle", "reach", render_mode="rgb_array", size=size)


def test_adapter_takes_an_image_size_as_an_array():
    env = SuiteEnv("bundle", "reach", render_mode="rgb_array", size=np.array([48, 64]))
    env.reset(seed=0)
    assert env.render().shape == (48, 64, 3)


def test_adapter_refuses_a_step_before_reset_unreal_actions_and_options():
    """A step before reset() ended in "float() argument must be ... not 'NoneType'"; a complex
    action was cast with numpy's warning and a text one parsed; reset options were ignored."""
    import pytest

    env = SuiteEnv("bundle", "reach")
    with pytest.raises(RuntimeError, match=r"step\(\) before reset\(\)"):
        env.step(np.full(3, 0.5))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="real pressure fractions.*complex128"):
        env.step(np.array([0.5 + 1j, 0.5, 0.5]))
    with pytest.raises(ValueError, match="real pressure fractions.*<U"):
        env.step(np.array(["0.5", "0.5", "0.5"]))
    with pytest.raises(ValueError, match=r"takes no options, got \['bogus'\]"):
        env.reset(seed=0, options={"bogus": 1})
