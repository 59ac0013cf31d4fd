"""The free-space lower bound beside the roadmap's c_max: hand-built maps with hand-computed lengths."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from shapely.geometry import Polygon, box

from parcover_env.harness.rollout import add_free_space_ratio, makespan_ratio
from parcover_env.planning import free_space_bound, free_space_distances, plan_scenario, plan_summary
from parcover_env.planning.free_space import FREE_QUAD_SEGS, reflex_vertices
from parcover_env.scenarios import load_scenario
from parcover_env.world.map_model import map_model

ROOM = box(0.0, 0.0, 4.0, 3.0)
L_CORRIDOR = Polygon([(0, 0), (4, 0), (4, 4), (3, 4), (3, 1), (0, 1)])
"""A 1 m wide corridor along y in [0, 1], turning left at x in [3, 4]; the inner corner is (3, 1)."""


def _l_exact(r: float) -> float:
    """The L corridor's shortest path (0.5, 0.5) -> (3.5, 3.5) for a disc of radius ``r`` (derived by
    hand in :func:`test_l_corridor_is_two_tangents_and_the_arc_around_the_inflated_corner`)."""
    dc = math.sqrt(6.5)
    apart = math.radians(360 - (math.degrees(math.atan2(-0.5, -2.5)) % 360 - math.degrees(math.atan2(2.5, 0.5))))
    return 2 * math.sqrt(dc**2 - r**2) + r * (apart - 2 * math.acos(r / dc))


def test_empty_room_is_the_straight_line():
    d = free_space_distances(ROOM, (0.5, 0.5), [(3.5, 2.5), (0.5, 2.5), (2.0, 0.5)], radius=0.2)
    np.testing.assert_allclose(d, [math.hypot(3.0, 2.0), 2.0, 1.5], atol=1e-9)


def test_target_too_close_to_a_wall_is_moved_to_where_the_centre_can_be():
    # (3.9, 0.5) is 0.1 m from the wall at x = 4; the disc's centre can get to (3.8, 0.5)
    d = free_space_distances(ROOM, (0.5, 0.5), [(3.9, 0.5)], radius=0.2)
    assert d[0] == pytest.approx(3.3, abs=1e-9)


def test_l_corridor_is_two_tangents_and_the_arc_around_the_inflated_corner():
    r = 0.2
    d = free_space_distances(L_CORRIDOR, (0.5, 0.5), [(3.5, 3.5)], radius=r)[0]
    # By hand: the inner corner c = (3, 1) inflated to a disc of radius r. S = (0.5, 0.5) and
    # T = (3.5, 3.5) are both sqrt(2.5^2 + 0.5^2) = sqrt(6.5) from c; each tangent leg is
    # sqrt(6.5 - r^2). Seen from c, S lies at atan2(-0.5, -2.5) = 191.31 deg and T at
    # atan2(2.5, 0.5) = 78.69 deg; the path passes on the corridor's side (through 270 deg):
    # 247.38 deg apart, less the 2 acos(r / sqrt(6.5)) = 171.00 deg the tangents take, leaves an
    # arc of 76.38 deg = 1.3331 rad.
    dc = math.sqrt(6.5)
    leg = math.sqrt(dc**2 - r**2)
    apart = math.radians(360 - (math.degrees(math.atan2(-0.5, -2.5)) % 360 - math.degrees(math.atan2(2.5, 0.5))))
    arc = r * (apart - 2 * math.acos(r / dc))
    exact = 2 * leg + arc
    assert exact == pytest.approx(2 * 2.54165 + 0.2 * 1.3331, abs=1e-4)  # the numbers in the comment
    assert exact == pytest.approx(_l_exact(r))
    # a lower bound, no shorter than the exact path for the corner's inscribed circle (module docstring)
    assert _l_exact(r * math.cos(math.pi / (4 * FREE_QUAD_SEGS))) - 1e-9 <= d <= exact + 1e-9
    assert exact - d < 2e-4
    fine = free_space_distances(L_CORRIDOR, (0.5, 0.5), [(3.5, 3.5)], radius=r, quad_segs=256)[0]
    assert fine == pytest.approx(exact, abs=1e-6)
    # a point robot bends at the corner itself: the two straight legs
    assert free_space_distances(L_CORRIDOR, (0.5, 0.5), [(3.5, 3.5)], radius=0.0)[0] == pytest.approx(2 * dc)


def test_only_the_inner_corner_of_the_l_is_reflex():
    np.testing.assert_allclose(reflex_vertices(L_CORRIDOR), [[3.0, 1.0]])
    assert len(reflex_vertices(ROOM)) == 0


def test_a_door_narrower_than_the_robot_separates_the_rooms():
    # a 0.3 m door (y in [0.95, 1.25]) through a 0.1 m wall (x in [2, 2.1])
    two_rooms = box(0, 0, 2, 2).union(box(2, 0.95, 2.1, 1.25)).union(box(2.1, 0, 4, 2))
    r = 0.1
    d = free_space_distances(two_rooms, (1.0, 1.0), [(3.1, 1.0)], radius=r, quad_segs=256)[0]
    # By hand: the centre passes the door at y >= 0.95 + r = 1.05, over the inflated lower jambs
    # c1 = (2, 0.95) and c2 = (2.1, 0.95). From S = (1, 1): |S c1| = sqrt(1 + 0.05^2), tangent leg
    # sqrt(|S c1|^2 - r^2); S is at atan2(0.05, -1) from c1, the tangent point acos(r / |S c1|)
    # from it, then the arc up to the circle's top (90 deg), 0.1 m along y = 1.05, and the mirror
    # image down to T = (3.1, 1) (2.1 m in a straight line).
    dc = math.hypot(1.0, 0.05)
    leg = math.sqrt(dc**2 - r**2)
    arc = r * (math.atan2(0.05, -1.0) - math.acos(r / dc) - math.pi / 2)
    assert d == pytest.approx(2 * (leg + arc) + 0.1, abs=1e-6)
    assert d == pytest.approx(2.1025, abs=1e-4)
    assert free_space_distances(two_rooms, (1.0, 1.0), [(3.1, 1.0)], radius=0.16)[0] == math.inf


def test_obstacle_between_start_and_target_makes_a_detour():
    room = box(0, 0, 4, 3).difference(box(1.5, 0, 2.5, 2.0))  # a wall from the floor, 1 m free above it
    d = free_space_distances(room, (0.5, 0.5), [(3.5, 0.5)], radius=0.0)[0]
    # up to the wall's top corners and down again: sqrt(1^2 + 1.5^2) twice plus the 1 m top
    assert d == pytest.approx(2 * math.hypot(1.0, 1.5) + 1.0, abs=1e-9)


def test_bad_input_is_one_value_error():
    with pytest.raises(ValueError, match="radius"):
        free_space_distances(ROOM, (0.5, 0.5), [(1, 1)], radius=-0.1)
    with pytest.raises(ValueError, match="finite"):
        free_space_distances(ROOM, (math.nan, 0.5), [(1, 1)], radius=0.1)


@pytest.mark.parametrize("name", ["office", "tree", "hallway", "t_room", "triangle_room"])
def test_scenario_bounds_are_ordered(name):
    s = load_scenario(name)
    plan = plan_scenario(s, s.n_robots_fixed)
    assert plan.c_free == free_space_bound(s)
    assert 0 < plan.c_free < plan.c_route <= plan.c_max + 1e-9
    summary = plan_summary(plan)
    assert summary["c_free"] == plan.c_free and summary["c_route"] == plan.c_route
    json.dumps(plan.to_dict())


def test_office_bound_by_value_and_against_a_grid():
    s = load_scenario("office")
    d = free_space_distances(map_model(s.map, include_unknown=False).free, (s.start.x, s.start.y), s.kpois,
                             s.robot.radius)
    # a 1 cm grid with 16-connectivity (tests of this branch, by hand) gave 2.174 / 4.916 m: a grid path
    # is at most 1 / cos(13.3 deg) = 2.75 % longer than the straight one, never shorter
    np.testing.assert_allclose(d, [2.152, 4.884], atol=1e-3)
    assert np.all(d <= [2.174, 4.916]) and np.all(d >= np.array([2.174, 4.916]) / 1.0275)
    plan = plan_scenario(s)
    assert plan.c_max == pytest.approx(7.473, abs=1e-3) and plan.c_route == pytest.approx(6.618, abs=1e-3)


def test_makespan_ratio_against_the_free_space_bound():
    assert makespan_ratio(30.0, 4.0, 0.2) == pytest.approx(1.5)  # 30 s against 4 m at 0.2 m/s = 20 s
    assert makespan_ratio(None, 4.0, 0.2) is None
    assert math.isnan(makespan_ratio(30.0, 0.0, 0.2))
    plan = plan_scenario(load_scenario("office"))
    out = add_free_space_ratio({"makespan": 32.3, "max_speed": 0.2, "makespan_ratio": 0.864}, plan)
    assert out["c_free"] == plan.c_free
    assert out["makespan_ratio_free"] == pytest.approx(32.3 / (plan.c_free / 0.2))
    assert out["makespan_ratio_free"] == pytest.approx(1.3226, abs=1e-4)


def test_path_bends_at_the_corners_of_a_triangle():
    room = box(0, 0, 4, 3).difference(Polygon([(1.5, 0.5), (2.5, 0.5), (2.0, 2.5)]))
    # a point robot from (0.5, 1) to (3.5, 1) passes under the triangle, by its two lower corners
    d = free_space_distances(room, (0.5, 1.0), [(3.5, 1.0)], radius=0.0)[0]
    assert d == pytest.approx(2 * math.hypot(1.0, 0.5) + 1.0, abs=1e-9)
    np.testing.assert_allclose(sorted(map(tuple, reflex_vertices(room))), [(1.5, 0.5), (2.0, 2.5), (2.5, 0.5)])


def test_no_room_for_the_robot_and_no_targets():
    np.testing.assert_array_equal(free_space_distances(box(0, 0, 1, 1), (0.5, 0.5), [(0.5, 0.5), (0.6, 0.6)],
                                                       radius=0.6), [math.inf, math.inf])
    assert free_space_distances(ROOM, (0.5, 0.5), np.zeros((0, 2)), radius=0.2).shape == (0,)


def test_one_chord_per_quarter_circle_is_still_a_lower_bound():
    coarse = free_space_distances(L_CORRIDOR, (0.5, 0.5), [(3.5, 3.5)], radius=0.2, quad_segs=1)[0]
    assert _l_exact(0.2 * math.cos(math.pi / 4)) < coarse < _l_exact(0.2) - 0.03  # 3 cm short at one chord
    with pytest.raises(ValueError, match="quad_segs"):
        free_space_distances(L_CORRIDOR, (0.5, 0.5), [(3.5, 3.5)], radius=0.2, quad_segs=0)
