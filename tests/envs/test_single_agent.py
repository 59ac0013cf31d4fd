"""The Gymnasium single-robot wrapper."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import parcover_env  # noqa: F401  (registers the gymnasium id)


def test_t_room_passes_gymnasium_checker_with_render_checks_headless(monkeypatch):
    """``check_env`` builds the env once per declared render mode, ``human`` included; without a
    display that mode shows nothing and warns once instead of raising."""
    import warnings

    from parcover_env.viz import render

    monkeypatch.setattr(render, "_has_display", lambda: False)
    monkeypatch.setattr(render, "_WARNED", set())
    monkeypatch.setattr(render.cv2, "imshow", lambda *a: pytest.fail("no window may open without a display"))
    env = gym.make("parcover_env/SingleRobotCoverage-v0", scenario="t_room")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)  # render checks on: rgb_array frames and the human mode
        human = gym.make("parcover_env/SingleRobotCoverage-v0", scenario="t_room", render_mode="human")
        human.reset(seed=0)
        assert human.render() is None and human.render() is None
        human.close()
    shown_nothing = [w for w in caught if "render_mode='human' shows nothing: no display" in str(w.message)]
    assert len(shown_nothing) == 1, [str(w.message) for w in caught]
    obs, _ = env.reset(seed=0)
    obs2, rew, term, trunc, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
    assert obs2.shape == obs.shape and "reward_progress" in info


def test_multi_robot_scenario_is_refused():
    with pytest.raises(ValueError, match="needs 1"):
        gym.make("parcover_env/SingleRobotCoverage-v0", scenario="office")
