"""The shift test: a scan pins a pose down in a closed room, not along a corridor nor with few echoes."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.localization.sonar.pin_down import shift_increase, shifted_errors
from parcover_env.sensors.sonar import simulate_beams

SONAR = parcover_env.load_scenario("t_room").robot.sonar
ANGLES = np.radians(np.arange(0, 360, 5.0))


def _box(x0, y0, x1, y1):
    return np.array([[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]], dtype=float)


def _scan(pose, walls):
    return simulate_beams(SONAR, np.asarray(pose, float)[None, :2], (pose[2] + ANGLES)[None, :], walls,
                          np.zeros((0, 2)), 0.0, np.array([-1]))[0]


def _increase(pose, walls, ranges, trim=0.0):
    e = shifted_errors(ranges, ANGLES, np.asarray(pose, float), segments=walls, sonar=SONAR, others=np.zeros((0, 2)),
                       radius=0.2, clip=0.5, step=0.2, trim=trim)
    assert e.shape == (9,) and e[0] == pytest.approx(0.0, abs=1e-12)  # the scan's own pose matches exactly
    return shift_increase(e)


def test_closed_room_pins_the_pose_down_a_corridor_does_not():
    room = _box(-1.0, -1.0, 1.5, 1.2)
    pose = np.array([0.1, 0.0, 0.3])
    assert _increase(pose, room, _scan(pose, room)) > 0.02
    corridor = np.array([[-40.0, -0.8, 40.0, -0.8], [-40.0, 0.8, 40.0, 0.8]])  # ends far beyond the range
    assert _increase(pose, corridor, _scan(pose, corridor)) == pytest.approx(0.0, abs=1e-9)


def test_trimmed_error_sees_that_few_echoes_pin_nothing():
    """Only a short wall within range: shifted, its few readings change (untrimmed: an increase), but
    they are among the trimmed worst ones, so the acceptance error does not change at all."""
    wall = np.array([[2.0, -0.05, 2.0, 0.05]])
    pose = np.array([0.0, 0.0, 0.0])
    ranges = _scan(pose, wall)
    echoes = int((ranges < SONAR.range_max).sum())
    assert 0 < echoes <= 0.1 * len(ANGLES)
    assert _increase(pose, wall, ranges) > 0.0
    assert _increase(pose, wall, ranges, trim=0.1) == pytest.approx(0.0, abs=1e-12)


def test_shift_increase_is_the_smallest_worsening():
    assert shift_increase(np.array([0.01, 0.05, 0.03, 0.02])) == pytest.approx(0.01)
    assert shift_increase(np.array([0.04, 0.03, 0.09])) == pytest.approx(-0.01)
