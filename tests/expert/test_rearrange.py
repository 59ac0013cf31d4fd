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
from parcover_env.localization.sonar.subgoals import NodeScores, densify, unblocked_angles
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
