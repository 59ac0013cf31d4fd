"""Pure avoidance functions: brake ramp, lane, sidestep, turn away (values on hand-built cases)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.expert.avoidance import brake_factor, lane_gap, sidestep, turn_away


def test_brake_factor_ramps_from_stop_to_slow():
    assert brake_factor(0.1, 0.2, 0.4) == 0.0
    assert brake_factor(0.2, 0.2, 0.4) == 0.0
    assert brake_factor(0.25, 0.2, 0.4) == pytest.approx(0.25)
    assert brake_factor(0.4, 0.2, 0.4) == 1.0
    assert brake_factor(3.0, 0.2, 0.4) == 1.0


def test_lane_gap_nearest_robot_in_the_swept_lane():
    xy = np.array([[0.0, 0.0], [2.0, 0.1], [1.0, -0.2], [1.0, 0.5], [-0.5, 0.0]])
    assert lane_gap(xy, 0, 0.0, 0.38, 0.33) == (pytest.approx(math.hypot(1.0, 0.2) - 0.33), 2)
    assert lane_gap(xy, 0, math.pi / 2, 0.38, 0.33) == (math.inf, -1)  # (1, 0.5) is 1 m off that line
    assert lane_gap(xy, 0, math.pi, 0.38, 0.33) == (pytest.approx(0.5 - 0.33), 4)


def test_sidestep_turns_perpendicular_on_the_side_of_the_way():
    out = sidestep(np.zeros(2), np.array([1.0, 0.0]), np.array([2.0, 0.5]))
    assert np.allclose(out, [0.0, math.hypot(2.0, 0.5)])
    out = sidestep(np.zeros(2), np.array([1.0, 0.0]), np.array([2.0, -0.5]))
    assert np.allclose(out, [0.0, -math.hypot(2.0, 0.5)])


def test_turn_away_from_the_nearest_echo():
    angles = np.radians([90.0, -90.0])
    assert turn_away(np.array([0.3, 2.0]), angles, 0.2, 0.4, 1.5) == pytest.approx(-0.75)
    assert turn_away(np.array([2.0, 0.1]), angles, 0.2, 0.4, 1.5) == pytest.approx(1.5)
    assert turn_away(np.array([0.5, 0.45]), angles, 0.2, 0.4, 1.5) == 0.0
    assert turn_away(np.zeros(0), np.zeros(0), 0.2, 0.4, 1.5) == 0.0
