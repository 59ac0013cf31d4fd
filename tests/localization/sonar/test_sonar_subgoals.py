"""Subgoal optimization of seed B §3: path nodes, eq. 1 bias, availability, team subgoal, rearrangement."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import MapConfig
from parcover_env.localization.sonar.features import MapFeature, map_features
from parcover_env.localization.sonar.subgoals import (
    best_pair,
    choose_subgoal,
    densify,
    scan_bias,
    score_nodes,
    team_subgoal,
    unblocked_angles,
    unblocked_scan_angle,
    wall_readings,
)
from parcover_env.world.map_model import MapModel

ROOM = MapModel.from_config(MapConfig(size=(3.0, 3.0)))
FEATS = map_features(ROOM)
STEP = math.radians(5)


def corner(x, y):
    return next(f for f in FEATS if np.allclose(f.point, (x, y)))


def test_densify_spacing_vertices_and_arclength():
    p = densify([[0, 0], [1, 0], [1, 0], [1, 2]], step=0.3, s0=-0.5)
    gaps = np.hypot(*np.diff(p.xy, axis=0).T)
    assert gaps.max() <= 0.3 + 1e-9 and gaps.min() > 0
    assert any(np.allclose(q, [1, 0]) for q in p.xy)
    assert p.s[0] == -0.5 and p.s[-1] == pytest.approx(2.5)
    assert p.length == pytest.approx(3.0)
    assert np.allclose(p.point(0.5), [1.0, 0.0])
    assert np.allclose(p.xy[p.index(10.0)], [1, 2])
    with pytest.raises(ValueError, match="path"):
        densify([[0, 0, 0]])
    with pytest.raises(ValueError, match="step"):
        densify([[0, 0], [1, 1]], step=0)


def test_bias_zero_on_bisector_and_paper_example():
    c = corner(0.0, 0.0)  # walls along +x and +y
    on_bisector = [[1.0, 1.0]]
    assert scan_bias(on_bisector, [c])[0, 0] == pytest.approx(0.0, abs=1e-12)
    # the paper's example: line of sight 15 deg from one wall, 75 deg from the other -> B = 60 deg
    a = math.radians(15)
    b = scan_bias([[math.cos(a), math.sin(a)]], [c])[0, 0]
    assert math.degrees(b) == pytest.approx(60.0)


def test_wall_readings_specular_and_range():
    c = corner(0.0, 0.0)
    near = wall_readings([[1.0, 1.0]], c, range_max=2.54, step=STEP)
    assert near[0, 0] > 10 and near[0, 1] > 10
    spec = wall_readings([[1.0, 1.0]], c, range_max=2.54, step=STEP, incidence_max=math.radians(20))
    assert 2 <= spec[0, 0] < near[0, 0]
    # foot of the perpendicular off the wall's far end: the specular wall returns nothing
    short = wall_readings([[2.9, 0.2]], corner(3.0, 3.0), range_max=2.54, step=STEP,
                          incidence_max=math.radians(5))
    assert short[0].min() == 0


def test_score_nodes_range_condition_and_best_feature():
    nodes = np.array([[0.6, 0.6], [1.5, 1.5], [0.6, 2.4]])
    s = score_nodes(nodes, ROOM, FEATS, 0.15, 2.54, STEP, math.radians(20))
    assert np.isfinite(s.bias).all()
    assert np.allclose(FEATS[s.feature[0]].point, [0, 0])
    assert np.allclose(FEATS[s.feature[2]].point, [0, 3])
    short = score_nodes(nodes, ROOM, FEATS, 0.15, 1.0, STEP, math.radians(20))
    assert np.isinf(short.bias[1]) and short.feature[1] == -1  # every corner is 2.1 m away
    strict = score_nodes(nodes, ROOM, FEATS, 0.15, 2.54, STEP, min_wall_length=5.0)
    assert np.isinf(strict.bias).all()
    with pytest.raises(ValueError, match="range"):
        score_nodes(nodes, ROOM, FEATS, 2.0, 1.0, STEP)


def test_choose_subgoal_window_ties_and_fallback():
    s = np.arange(6.0)
    bias = np.array([0.0, 0.5, 0.1, 0.11, 0.9, 0.2])
    assert choose_subgoal(s, bias, 1, 5, tie_tol=0.0) == 2
    assert choose_subgoal(s, bias, 1, 5, tie_tol=0.02) == 3
    assert choose_subgoal(s, np.full(6, np.inf), 1, 4, 0.0) == 4


def test_team_subgoal_uses_the_worst_robot():
    p = densify([[0, 0], [5, 0]], 0.5)
    good_for_0 = np.where(np.isclose(p.s, 3.0), 0.0, 1.0)
    bad_for_1 = np.where(np.isclose(p.s, 2.0), 2.0, 0.5)  # robot 1 sits at sigma - 1
    assert team_subgoal([p], [good_for_0], np.array([0.0]), 1.0, 4.5, 0.5, 0.0) == pytest.approx(3.0)
    sigma = team_subgoal([p, p], [good_for_0, bad_for_1], np.array([0.0, 1.0]), 1.0, 4.5, 0.5, 0.0)
    assert sigma != pytest.approx(3.0)


def test_unblocked_scan_angle():
    c = corner(0.0, 0.0)
    me = np.array([1.2, 1.2])
    free = unblocked_scan_angle(me, c, np.zeros((0, 2)), 0.165, 2.54)
    assert free > math.radians(60)
    blocker = unblocked_scan_angle(me, c, [[0.6, 0.6]], 0.165, 2.54)
    aside = unblocked_scan_angle(me, c, [[2.5, 2.5]], 0.165, 2.54)
    assert blocker < free - math.radians(20)
    assert aside == pytest.approx(free)


def test_bisector_rearrangement_puts_the_pair_abreast_of_the_feature():
    """§4: two robots one behind the other on one path towards corner F. The leader moves to where
    its path crosses the perpendicular bisector of (centre, F); the other takes the bisector point
    nearest its subgoal, slid to keep the separation. Neither then blocks the other's scan of F."""
    from parcover_env.localization.sonar.subgoals import bisector_rearrangement

    room = MapModel.from_config(MapConfig(size=(5.0, 3.0)))
    f = next(x for x in map_features(room) if np.allclose(x.point, (5.0, 0.0)))
    path = densify(np.array([[0.3, 1.0], [4.6, 1.0]]), 0.02)
    before = np.array([[2.0, 1.0], [1.4, 1.0]])
    res = bisector_rearrangement(before, [path, path], [1.7, 1.1], f.point, min_separation=0.4)
    c, m = before.mean(axis=0), 0.5 * (before.mean(axis=0) + f.point)
    n = (f.point - c) / np.hypot(*(f.point - c))
    assert res.subgoals[0] == pytest.approx([m[0] + (1.0 - m[1]) * -n[1] / n[0], 1.0], abs=0.02)
    assert abs((res.subgoals[1] - m) @ n) < 1e-9 and res.on_path == (True, False)
    assert np.hypot(*(res.subgoals[1] - res.subgoals[0])) >= 0.4 - 1e-9

    def worst_angle(pts):  # min_i A_i of §3.2 with the AmigoBot's 2.54 m range
        return min(unblocked_scan_angle(pts[i], f, pts[[1 - i]], 0.165, 2.54) for i in range(2))

    def sight_clearance(pts):  # smallest distance from a robot's line of sight to F to the other robot
        out = []
        for i in range(2):
            a, d = pts[i], f.point - pts[i]
            t = np.clip((pts[1 - i] - a) @ d / (d @ d), 0.0, 1.0)
            out.append(np.hypot(*(a + t * d - pts[1 - i])))
        return min(out)

    assert sight_clearance(before) < 0.165 < sight_clearance(res.subgoals)  # blocked -> clear
    assert worst_angle(res.subgoals) > worst_angle(before) + math.radians(20)
    # two parallel paths: both robots cross the bisector and move to their crossings
    lower = densify(np.array([[0.3, 0.6], [4.6, 0.6]]), 0.02)
    res2 = bisector_rearrangement(np.array([[2.0, 1.0], [1.6, 0.6]]), [path, lower], [1.7, 1.3], f.point, 0.3)
    assert res2.on_path == (True, True) and res2.subgoals[:, 1] == pytest.approx([1.0, 0.6])


def test_bisector_rearrangement_windows_and_slide_past_a_wall():
    """A crossing outside a robot's arclength window does not count (that robot goes off its path);
    an off-path robot that cannot slide away from its teammate (a wall) slides past it instead."""
    from parcover_env.localization.sonar.subgoals import bisector_rearrangement

    room = MapModel.from_config(MapConfig(size=(5.0, 3.0)))
    f = next(x for x in map_features(room) if np.allclose(x.point, (5.0, 0.0)))
    path = densify(np.array([[0.3, 1.0], [4.6, 1.0]]), 0.02)
    before = np.array([[2.0, 1.0], [1.4, 1.0]])
    res = bisector_rearrangement(before, [path, path], [1.7, 1.1], f.point, 0.4, windows=[(1.0, 2.0), (0.0, 2.0)])
    assert res.on_path == (False, False)  # robot 0's crossing (x ~ 3.6) lies beyond arclength 2.0
    m, u = res.bisector
    n = np.array([u[1], -u[0]])
    assert abs((res.subgoals - m) @ n).max() < 1e-9  # both on the bisector
    assert res.subgoals[0] == pytest.approx(before[0] - ((before[0] - m) @ n) * n)
    # the bisector runs from the top-left to the bottom-right; forbid the side away from robot 0
    away = np.sign((res.subgoals[1] - res.subgoals[0]) @ u)
    assert away != 0

    def free(pts):
        return np.asarray(pts) @ u * away <= res.subgoals[0] @ u * away + 1e-9

    res2 = bisector_rearrangement(before, [path, path], [1.7, 1.1], f.point, 0.4, free=free,
                                  windows=[(1.0, 2.0), (0.0, 2.0)])
    assert np.hypot(*(res2.subgoals[1] - res2.subgoals[0])) >= 0.4 - 1e-9
    assert (res2.subgoals[1] - res2.subgoals[0]) @ u * away < 0  # it slid past robot 0


def _corner_xy():
    """A concave corner at the origin, walls 3 m long along +x and +y (free space in between)."""
    return MapFeature(0, np.zeros(2), np.array([[1.0, 0.0], [0.0, 1.0]]), np.array([[0.0, 1.0], [1.0, 0.0]]),
                      np.array([3.0, 3.0]))


def test_unblocked_angles_and_best_pair_by_hand():
    """Robot a at (2, 2) scans the corner over 143.1 deg (far wall ends (3, 0) and (0, 3) at
    +-71.6 deg of the corner's bearing) + 2 x 2 deg margin = 147.1 deg. Robot b at B1 = (1, 1) stands
    on a's line of sight: its disc (0.165 m at 1.414 m) hides 2 asin(0.165 / 1.414) = 13.4 deg of it
    -> 133.7 deg, while a lies behind b (b scans 216.8 + 4 deg unblocked). At B2 = (2.4, 1.6), abreast
    of a, 0.566 m away: a is free (b's bearing is 90 deg off, 16.9 deg half-width), and a hides
    4.2 deg of b's 144.9 deg -> min 140.7 deg. B2 is the better assignment unless the pair must stay
    0.6 m apart."""
    f = _corner_xy()
    a, b = [[2.0, 2.0]], [[1.0, 1.0], [2.4, 1.6]]
    deg = np.degrees
    assert deg(unblocked_angles(a, f, b, 0.165, 10.0)).ravel() == pytest.approx([133.7, 147.1], abs=1.0)
    assert deg(unblocked_angles(b, f, a, 0.165, 10.0)).ravel() == pytest.approx([220.8, 140.7], abs=1.0)
    best = best_pair(a, b, f, 0.3, 0.165, 10.0)
    assert (best.a, best.b) == (0, 1) and deg(best.value) == pytest.approx(140.7, abs=1.0)
    apart = best_pair(a, b, f, 0.6, 0.165, 10.0)
    assert (apart.a, apart.b) == (0, 0) and deg(apart.value) == pytest.approx(133.7, abs=1.0)
    # ties go to the cheapest pair; no pair far enough apart: none
    tie = best_pair(a, [[2.4, 1.6], [2.4, 1.6]], f, 0.3, 0.165, 10.0, cost=[[1.0, 0.0]])
    assert tie.b == 1
    assert best_pair(a, b, f, 5.0, 0.165, 10.0).a == -1
