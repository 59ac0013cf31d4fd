"""Subgoal rearrangement (Kim, Pearce & Amato §3.2): robots sharing a sector share a feature."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from parcover_env.config import MapConfig
from parcover_env.expert.config import NavigatorConfig
from parcover_env.expert.rearrange import SubgoalRearranger
from parcover_env.localization.sonar.features import MapFeature
from parcover_env.localization.sonar.sectors import Sector
from parcover_env.localization.sonar.subgoals import NodeScores, densify, unblocked_angles, unblocked_scan_angle
from parcover_env.world.map_model import MapModel

R, RANGE = 0.165, 10.0
# the floor near the corner (x + y < 1.9) is blocked, so §4's bisector (x + y = 1.5 for the pair
# below) has no free point: the pair can only move along its paths
ROOM = MapModel.from_config(MapConfig(size=(6.0, 6.0), obstacles=(((0.0, 0.0), (1.9, 0.0), (0.0, 1.9)),)))
CORNER = MapFeature(0, np.zeros(2), np.array([[1.0, 0.0], [0.0, 1.0]]), np.array([[0.0, 1.0], [1.0, 0.0]]),
                    np.array([3.0, 3.0]))
PARAMS = NavigatorConfig(max_shift=2.0)
# robot 0 stops at (2, 2); robot 1 on the way from (1, 1) (on 0's line of sight to the corner) to
# (2.4, 1.6) (abreast of robot 0, 0.566 m away), its subgoal at (1, 1)
PATHS = [densify([[2.0, 2.6], [2.0, 2.0]], 0.05), densify([[1.0, 1.0], [2.4, 1.6]], 0.05)]
# (the corner's feature is drawn by hand: its own walls, 3 m long; nothing checks the floor there)
TARGETS = np.array([PATHS[0].s[-1], 0.0])
WINDOWS = np.array([[PATHS[0].s[-1], PATHS[0].s[-1]], [0.0, PATHS[1].s[-1]]])  # robot 0 stays


def _scores(path):
    k = len(path.xy)
    return NodeScores(np.zeros(k), np.zeros(k, dtype=int), np.ones((k, 1), dtype=bool))


def _rearranger(sectors):
    return SubgoalRearranger([CORNER], sectors, ROOM, R, RANGE, math.pi / 2, 0.0, PARAMS)


def _worst(a, b):
    return min(unblocked_angles([a], CORNER, [b], R, RANGE)[0, 0], unblocked_angles([b], CORNER, [a], R, RANGE)[0, 0])


def test_a_blocking_pair_in_one_sector_moves_to_the_abreast_assignment():
    """Robot 1 at (1, 1) hides 13.4 deg of robot 0's view of the corner (worst angle 134 deg, by hand
    in test_sonar_subgoals). Along robot 1's path the worst angle is largest at its far end
    (2.4, 1.6), abreast of robot 0 (140.5 deg by the same count): the rearranged subgoal."""
    one = [Sector(ROOM.free, frozenset({0}))]
    res = _rearranger(one).rearrange(PATHS, [_scores(p) for p in PATHS], TARGETS, WINDOWS, np.arange(2))
    assert res.pairs == 1 and not np.isfinite(res.goals).any()
    assert res.targets[0] == pytest.approx(TARGETS[0])
    new = PATHS[1].point(res.targets[1])
    assert new == pytest.approx([2.4, 1.6], abs=0.05)
    assert math.degrees(_worst([2.0, 2.0], new)) == pytest.approx(140.5, abs=1.0)
    assert math.degrees(_worst([2.0, 2.0], [1.0, 1.0])) == pytest.approx(134.0, abs=1.0)


def test_no_rearrangement_across_sectors_or_without_blocking():
    """Fig. 10: robots in different sectors use different features and keep their subgoals."""
    left = shapely.box(0.0, 0.0, 1.5, 6.0)
    two = [Sector(left, frozenset({0})), Sector(ROOM.free.difference(left), frozenset({0}))]
    scores = [_scores(p) for p in PATHS]
    res = _rearranger(two).rearrange(PATHS, scores, TARGETS, WINDOWS, np.arange(2))
    assert res.pairs == 0 and np.array_equal(res.targets, TARGETS)
    # robot 1 at (3, 1): robot 0 is 63 deg off its view of the corner and robot 1 is 90 deg off robot
    # 0's (half-widths 6.7 deg): neither blocks the other
    one = [Sector(ROOM.free, frozenset({0}))]
    paths = [PATHS[0], densify([[3.0, 1.0], [3.5, 1.0]], 0.05)]
    windows = np.array([WINDOWS[0], [0.0, 0.5]])
    res = _rearranger(one).rearrange(paths, [_scores(p) for p in paths], TARGETS, windows, np.arange(2))
    assert res.pairs == 0 and np.array_equal(res.targets, TARGETS)


# Run-time blocking (our extension): robot 0 drives along y = 2 from x = 1.2 to 3.4, its subgoal at
# (2, 2) (label 0.8); robot 1 is far away in the room's other corner; a body stands where the plan
# did not put one (a teammate done with its route, left where its run took it).
LANE = [densify([[1.2, 2.0], [3.4, 2.0]], 0.05), densify([[4.0, 5.0], [5.0, 5.0]], 0.05)]
LANE_TARGETS = np.array([0.8, 0.0])
LANE_WINDOWS = np.array([[0.0, LANE[0].s[-1]], [0.0, 1.0]])


def _react(standing):
    rr = SubgoalRearranger([CORNER], [Sector(ROOM.free, frozenset({0}))], ROOM, R, RANGE, math.pi / 2, 0.0,
                           NavigatorConfig())  # the default max_shift, 0.6 m
    return rr.rearrange(LANE, [_scores(p) for p in LANE], LANE_TARGETS.copy(), LANE_WINDOWS, np.array([0]),
                        standing=standing)


def _angle(xy, bodies):
    return math.degrees(unblocked_scan_angle(xy, CORNER, np.reshape(bodies, (-1, 2)), R, RANGE))


def test_rearrangement_reacts_to_a_body_standing_in_the_line_of_sight():
    """By hand: from (2, 2) the corner's walls (3 m long) span bearings -63.43 .. 153.43 deg through
    225 deg, 143.13 deg, + 2 x 2 deg margin = 147.1 deg. A body at (1.2, 1.2), 1.131 m away on the
    line to the corner, hides 2 asin(0.165 / 1.131) = 16.8 deg: 130.4 deg left. Robot 0 alone is
    blocked (its teammate is not in its way), so it moves alone along its path, as far as the 0.6 m
    cap allows, to (1.4, 2): bearings -51.34 .. 144.46 deg, 164.2 + 4 = 168.2 deg; the body, 0.825 m
    away, hides 2 asin(0.165 / 0.825) = 23.1 deg: 145.1 deg, 14.7 deg gained."""
    body = np.array([[1.2, 1.2]])
    res = _react(body)
    assert res.reacted == (0,) and res.pairs == 0 and not np.isfinite(res.goals).any()
    assert LANE_TARGETS[0] - res.targets[0] == pytest.approx(0.6, abs=1e-9)  # the shift cap
    new = LANE[0].point(res.targets[0])
    assert new == pytest.approx([1.4, 2.0], abs=1e-9)
    assert res.targets[1] == LANE_TARGETS[1]  # the robot that is not active keeps its subgoal
    assert _angle([2.0, 2.0], []) == pytest.approx(147.1, abs=0.6)
    assert _angle([2.0, 2.0], body) == pytest.approx(130.4, abs=0.6)
    assert _angle(new, body) == pytest.approx(145.1, abs=0.6)


def test_no_reaction_without_the_body_or_with_a_body_out_of_the_way():
    for standing in (None, np.zeros((0, 2)), np.array([[3.5, 3.5]])):  # (3.5, 3.5): behind robot 0
        res = _react(standing)
        assert res.reacted == () and res.pairs == 0 and np.array_equal(res.targets, LANE_TARGETS)
