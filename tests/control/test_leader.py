"""Leader go-to-goal (our law on eq. 2's unicycle kinematics): reaches goals from any heading, respects saturation."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.control.leader import go_to_goal
from parcover_env.geometry import rotate


def _drive(start_heading: float, goal: np.ndarray, steps: int = 400, dt: float = 0.1):
    p, th = np.zeros(2), start_heading
    for _ in range(steps):
        local = rotate(goal - p, -th)
        v, w = go_to_goal(local, 0.3, 1.5)
        assert -0.3 <= v <= 0.3 and -1.5 <= w <= 1.5
        p = p + v * dt * np.array([np.cos(th), np.sin(th)])
        th += w * dt
    return p


@pytest.mark.parametrize("heading", np.linspace(-np.pi, np.pi, 13))
def test_reaches_goal_from_any_heading(heading):
    goal = np.array([1.2, -0.7])
    assert np.hypot(*(_drive(heading, goal) - goal)) < 0.02


def test_goal_behind_turns_in_place_first():
    v, w = go_to_goal(np.array([-1.0, 0.01]), 0.3, 1.5)
    assert v == pytest.approx(0.0, abs=1e-3) and abs(w) == 1.5


def test_speed_scale_caps_speed():
    v, _ = go_to_goal(np.array([5.0, 0.0]), 0.3, 1.5, speed_scale=0.5)
    assert v == pytest.approx(0.15)
