"""The Gymnasium single-robot wrapper."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import parcover_env  # noqa: F401  (registers the gymnasium id)


def test_t_room_passes_gymnasium_checker():
    env = gym.make("parcover_env/SingleRobotCoverage-v0", scenario="t_room")
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    obs2, rew, term, trunc, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
    assert obs2.shape == obs.shape and "reward_progress" in info


def test_multi_robot_scenario_is_refused():
    with pytest.raises(ValueError, match="needs 1"):
        gym.make("parcover_env/SingleRobotCoverage-v0", scenario="office")
