"""Parallel paths (Kim, Pearce & Amato §2): the route's segments replicated and translated per robot."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from parcover_env.config import MapConfig
from parcover_env.localization.sonar.parallel_paths import (
    lane_allowed,
    lane_offsets,
    lateral_offset,
    node_normals,
    parallel_path,
    with_start,
)
from parcover_env.localization.sonar.subgoals import densify
from parcover_env.world.map_model import MapModel

W, CLEAR, RAMP = 0.58, 0.415, 1.16  # hallway: lanes 2 r + slow_margin apart, r + slow_margin from walls
# a 10 m x 2 m corridor narrowed to 0.9 m (y in [0.55, 1.45]) for x in [4, 6]
CORRIDOR = MapModel.from_config(MapConfig(size=(10.0, 2.0), obstacles=(
    ((4.0, 0.0), (6.0, 0.0), (6.0, 0.55), (4.0, 0.55)), ((4.0, 1.45), (6.0, 1.45), (6.0, 2.0), (4.0, 2.0)))))
ROUTE = densify([[0.5, 1.0], [9.5, 1.0]], 0.05)


def _y_at(path, x):
    k = int(np.argmin(np.abs(path.xy[:, 0] - x)))
    assert abs(path.xy[k, 0] - x) < 1e-9
    return float(path.xy[k, 1])


def test_lane_offsets_centre_the_lanes_on_the_route():
    assert lane_offsets(2, W).tolist() == pytest.approx([0.29, -0.29])
    assert lane_offsets(3, 1.0).tolist() == pytest.approx([1.0, 0.0, -1.0])


def test_straight_corridor_lanes_are_the_centreline_offset_and_merge_where_it_narrows():
    """Lane points (x, 1 + 0.29) keep 0.415 m from the walls except within the narrowing and within
    sqrt(0.415^2 - 0.16^2) = 0.383 m of its corners (x in (3.617, 6.383)): nodes 3.65 ... 6.35 are
    blocked. The shift is 0.29 a, a = distance to the nearest blocked node or route end / 1.16 m."""
    blocked = ~lane_allowed(ROUTE, W / 2, CORRIDOR, CLEAR)
    xb = ROUTE.xy[blocked, 0]
    assert xb.min() == pytest.approx(3.65) and xb.max() == pytest.approx(6.35)
    for sign in (1, -1):
        lane = parallel_path(ROUTE, sign * W / 2, CORRIDOR, CLEAR, RAMP)
        assert _y_at(lane, 2.0) == pytest.approx(1.0 + sign * 0.29)       # full offset: 1.5 m from both
        assert _y_at(lane, 8.0) == pytest.approx(1.0 + sign * 0.29)
        assert _y_at(lane, 5.0) == pytest.approx(1.0)                      # merged in the narrowing
        assert _y_at(lane, 3.0) == pytest.approx(1.0 + sign * 0.29 * 0.65 / RAMP)  # ramping down
        assert _y_at(lane, 0.5) == pytest.approx(1.0) and _y_at(lane, 9.5) == pytest.approx(1.0)  # ends
        assert _y_at(lane, 1.0) == pytest.approx(1.0 + sign * 0.29 * 0.5 / RAMP)
        assert np.all(CORRIDOR.contains(lane.xy, margin=0.165))
    # robot 1 trails 0.5 m where the lanes merge (labels), abreast where they do not
    lane = parallel_path(ROUTE, -W / 2, CORRIDOR, CLEAR, RAMP, lag=0.5)
    k5, k2 = (int(np.argmin(np.abs(lane.xy[:, 0] - x))) for x in (5.0, 2.0))
    assert lane.s[k5] == pytest.approx(4.5 - 0.5) and lane.s[k2] == pytest.approx(1.5)
    assert np.all(np.diff(lane.s) > 0)
    with pytest.raises(ValueError, match="lag"):
        parallel_path(ROUTE, W / 2, CORRIDOR, CLEAR, RAMP, lag=RAMP)


def test_a_wide_corridor_keeps_the_lanes_everywhere_but_the_ends():
    wide = MapModel.from_config(MapConfig(size=(10.0, 2.0)))
    assert lane_allowed(ROUTE, W / 2, wide, CLEAR).all()
    lane = parallel_path(ROUTE, W / 2, wide, CLEAR, RAMP)
    inner = (lane.xy[:, 0] >= 0.5 + RAMP) & (lane.xy[:, 0] <= 9.5 - RAMP)
    assert np.allclose(lane.xy[inner, 1], 1.29)


def test_turn_lanes_meet_at_the_mitre_points_and_overshoot_is_trimmed():
    """Route (1, 1) -> (6, 1) -> (6, 6), a left turn. Translated segments of the left (inner) lane
    meet at (5.7, 1.3), those of the right (outer) lane at (6.3, 0.7); no lane node lies closer to
    the route than its shift."""
    room = MapModel.from_config(MapConfig(size=(8.0, 8.0)))
    route = densify([[1.0, 1.0], [6.0, 1.0], [6.0, 6.0]], 0.05)
    n = node_normals(route.xy)
    k = int(np.argmin(np.hypot(*(route.xy - (6.0, 1.0)).T)))
    assert n[k] == pytest.approx([-1.0, 1.0])  # mitre: sqrt(2) along the bisector
    for offset, mitre in ((0.3, (5.7, 1.3)), (-0.3, (6.3, 0.7))):
        lane = parallel_path(route, offset, room, CLEAR, RAMP)
        assert np.min(np.hypot(*(lane.xy - mitre).T)) < 1e-9
        d = shapely.distance(shapely.LineString(route.xy), shapely.points(lane.xy))
        mid = (lane.s > 1.0 + RAMP) & (lane.s < route.s[-1] - RAMP)
        assert np.all(d[mid] >= 0.3 - 1e-9)
        assert np.all(np.diff(lane.s) > 0)


def test_with_start_prepends_the_way_from_the_start():
    lane = parallel_path(ROUTE, W / 2, CORRIDOR, CLEAR, RAMP)
    p = with_start(lane, np.array([0.0, 1.0]), 0.05)
    assert p.xy[0].tolist() == [0.0, 1.0] and p.s[0] == pytest.approx(-0.5)
    assert np.all(np.diff(p.s) > 0) and with_start(lane, lane.xy[0], 0.05) is lane


def test_lateral_offset_is_across_the_mean_heading():
    assert lateral_offset(np.array([[0.0, 0.0], [0.0, 0.5]]), np.zeros(2)) == pytest.approx(0.5)
    assert lateral_offset(np.array([[1.0, 0.0], [0.0, 0.0]]), np.zeros(2)) == pytest.approx(0.0)
    h = np.full(2, math.pi / 2)  # heading +y: the x difference is lateral
    assert lateral_offset(np.array([[0.0, 0.0], [0.3, 2.0]]), h) == pytest.approx(0.3)
