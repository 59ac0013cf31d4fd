"""The ``contact`` reward's :func:`touching` at its boundaries: a robot exactly ``radius + gap`` from
a wall, or exactly ``2 radius + gap`` from another robot, does not touch; a hair closer does."""

from __future__ import annotations

import numpy as np

from parcover_env.mission.rewards import touching

WALL = np.array([[0.0, -1.0, 0.0, 1.0]])  # the segment x = 0, -1 <= y <= 1


def test_a_robot_exactly_radius_plus_gap_from_a_wall_does_not_touch_it():
    xy = np.array([[0.5, 0.0], [-0.4375, 0.0], [0.5, 5.0]])  # r + gap = 0.5: on the edge, inside, far
    assert touching(xy, WALL, 0.25, 0.25).tolist() == [0.0, 1.0, 0.0]


def test_robots_exactly_two_radii_plus_gap_apart_do_not_touch():
    xy = np.array([[10.0, 0.0], [10.75, 0.0], [20.0, 0.0], [20.0, 0.6875]])  # 2 r + gap = 0.75
    assert touching(xy, WALL, 0.25, 0.25).tolist() == [0.0, 0.0, 1.0, 1.0]
    assert touching(xy, np.zeros((0, 4)), 0.25, 0.25).tolist() == [0.0, 0.0, 1.0, 1.0]


def test_integer_positions_are_touching_as_floats():
    xy = [[1, 0], [3, 0], [4, 0]]
    out = touching(xy, WALL, 0.5, 0.75)
    assert out.dtype == float and out.tolist() == [1.0, 1.0, 1.0]  # 1 m < 1.25 m from the wall; 1 m < 1.75 m apart
    assert touching(xy, WALL, 0.5, 0.25).tolist() == [0.0, 1.0, 1.0]  # 1 m >= 0.75 m from the wall; 1 m < 1.25 m
