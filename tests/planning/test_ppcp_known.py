"""Hand-made graphs with known PPCP answers (star, path, comb, seed A Fig. 5(b), Fig. 1(b))."""

from __future__ import annotations

import json

import numpy as np
import pytest
from planning_graphs import graph_from

from parcover_env.planning import solve_ppcp


def _counts(tp):
    return sorted(b.n_robots for b in tp.branches)


def _check_blocks(plan):
    for tp in plan.turning_points:
        lo, hi = tp.robots
        ranges = sorted(b.robots for b in tp.branches)
        assert ranges[0][0] == lo and ranges[-1][1] == hi
        assert all(a[1] == b[0] for a, b in zip(ranges[:-1], ranges[1:], strict=False))
        assert all(b.leader == b.robots[0] for b in tp.branches)


def test_star_equal_arms_one_robot_per_arm_split_at_start():
    pos = {"s": (0, 0), 0: (2, 0), 1: (0, 2), 2: (-2, 0), 3: (0, -2)}
    g = graph_from(pos, [("s", k) for k in range(4)])
    plan = solve_ppcp(g, "s", [0, 1, 2, 3], method="heuristic")
    assert plan.r == 4 and plan.c_max == pytest.approx(2.0) and plan.c_p == pytest.approx(2.0)
    assert len(plan.turning_points) == 1
    tp = plan.turning_points[0]
    assert tp.position == (0.0, 0.0) and tp.distance == 0.0 and _counts(tp) == [1, 1, 1, 1]
    assert sorted(k for rp in plan.robots for k in rp.kpois) == [0, 1, 2, 3]
    _check_blocks(plan)


def test_path_graph_one_robot_visits_all_in_order():
    pos = {"s": (0, 0), "a": (1, 0), "b": (2, 0), "c": (3.5, 0)}
    g = graph_from(pos, [("s", "a"), ("a", "b"), ("b", "c")])
    plan = solve_ppcp(g, "s", ["a", "b", "c"])
    assert plan.r == 1 and plan.turning_points == ()
    (rp,) = plan.robots
    assert rp.kpois == (0, 1, 2)
    np.testing.assert_allclose(rp.kpoi_distance, [1.0, 2.0, 3.5])
    np.testing.assert_allclose(rp.path[[0, -1]], [[0, 0], [3.5, 0]])
    assert rp.cost == pytest.approx(3.5) and plan.c_max == pytest.approx(3.5)


def test_comb_three_teeth_splits_at_each_spine_node():
    pos = {"s": (0, 0), "x1": (1, 0), "x2": (2, 0), "x3": (3, 0), "t1": (1, 2), "t2": (2, 2), "t3": (3, 2)}
    g = graph_from(pos, [("s", "x1"), ("x1", "x2"), ("x2", "x3"), ("x1", "t1"), ("x2", "t2"), ("x3", "t3")])
    plan = solve_ppcp(g, "s", ["t1", "t2", "t3"], method="heuristic")
    assert plan.r == 3 and plan.n_leaves == 3 and plan.c_max == pytest.approx(5.0)
    tps = {tp.position: tp for tp in plan.turning_points}
    assert set(tps) == {(1.0, 0.0), (2.0, 0.0)}
    assert _counts(tps[(1.0, 0.0)]) == [1, 2] and tps[(1.0, 0.0)].robots == (0, 3)
    assert _counts(tps[(2.0, 0.0)]) == [1, 1] and tps[(2.0, 0.0)].distance == pytest.approx(2.0)
    _check_blocks(plan)
    costs = sorted(rp.cost for rp in plan.robots)
    np.testing.assert_allclose(costs, [3.0, 4.0, 5.0])


def test_fig5b_two_kpois_behind_one_tp():
    pos = {"S": (0, 0), "T": (3, 0), "A": (3, 1), "B": (3, -1)}
    g = graph_from(pos, [("S", "T"), ("T", "A"), ("T", "B")])
    plan = solve_ppcp(g, "S", ["A", "B"])
    assert plan.r == 2 and plan.c_max == pytest.approx(4.0) and plan.c_p == pytest.approx(4.0)
    (tp,) = plan.turning_points
    assert tp.position == (3.0, 0.0) and tp.distance == pytest.approx(3.0) and tp.robots == (0, 2)
    assert _counts(tp) == [1, 1] and {b.next_waypoint for b in tp.branches} == {(3.0, 1.0), (3.0, -1.0)}
    assert sorted(rp.kpois for rp in plan.robots) == [(0,), (1,)]


def test_fig1b_tours_merge_short_arms_at_unchanged_cost():
    pos = {"s": (0, 0), "a": (1, 0), "b": (0, 1), "c": (-3, 0)}
    g = graph_from(pos, [("s", "a"), ("s", "b"), ("s", "c")])
    paths = solve_ppcp(g, "s", ["a", "b", "c"], merge_tours=False, method="heuristic")
    tours = solve_ppcp(g, "s", ["a", "b", "c"], method="heuristic")
    assert paths.r == 3 and paths.method == "paths"
    assert tours.r == 2 and tours.method == "tours" and tours.c_p == pytest.approx(tours.c_max)
    assert sorted(rp.kpois for rp in tours.robots) in ([(0, 1), (2,)], [(1, 0), (2,)])


def test_interior_kpoi_is_credited_to_the_leader():
    pos = {"S": (0, 0), "k": (1, 0), "T": (3, 0), "A": (3, 1), "B": (3, -1)}
    g = graph_from(pos, [("S", "k"), ("k", "T"), ("T", "A"), ("T", "B")])
    plan = solve_ppcp(g, "S", ["k", "A", "B"], method="heuristic")
    assert plan.r == 2
    assert plan.robots[0].kpois[0] == 0 and plan.robots[0].kpoi_distance[0] == pytest.approx(1.0)
    assert 0 not in plan.robots[1].kpois


def test_given_r_minmax_star():
    pos = {"s": (0, 0), 0: (1, 0), 1: (0, 1), 2: (-1, 0), 3: (0, -1)}
    g = graph_from(pos, [("s", k) for k in range(4)])
    plan = solve_ppcp(g, "s", [0, 1, 2, 3], n_robots=2, method="heuristic")
    assert plan.r == 2 and plan.c_p == pytest.approx(3.0) and plan.method == "minmax"
    one = solve_ppcp(g, "s", [0, 1, 2, 3], n_robots=1)
    assert one.r == 1 and one.c_p == pytest.approx(7.0)


def test_more_robots_than_useful_stay_idle_at_start():
    pos = {"s": (0, 0), "a": (1, 0)}
    plan = solve_ppcp(graph_from(pos, [("s", "a")]), "s", ["a"], n_robots=3)
    assert plan.r == 3 and plan.c_p == pytest.approx(1.0)
    assert [len(rp.kpois) for rp in plan.robots] == [1, 0, 0]
    assert plan.robots[1].path.shape == (1, 2) and plan.robots[1].cost == 0.0
    json.dumps(plan.to_dict())


def test_bad_input_raises_value_error():
    pos = {"s": (0, 0), "a": (1, 0), "z": (5, 5)}
    g = graph_from(pos, [("s", "a")])
    with pytest.raises(ValueError, match=r"kpois\[1\]"):
        solve_ppcp(g, "s", ["a", "z"])
    with pytest.raises(ValueError, match="not in the roadmap"):
        solve_ppcp(g, "q", ["a"])
    with pytest.raises(ValueError, match="n_robots"):
        solve_ppcp(g, "s", ["a"], n_robots=0)
    with pytest.raises(ValueError, match="at least one KPOI"):
        solve_ppcp(g, "s", [])
    with pytest.raises(ValueError, match="method"):
        solve_ppcp(g, "s", ["a"], method="magic")


def test_tp_merge_tolerance_makes_one_multiway_tp():
    """Two forks 4 cm apart (a roadmap crossing a junction) are one 3-way TP under the tolerance,
    two 2-way TPs without it."""
    pos = {"s": (0, 0), "j1": (2.0, 0), "j2": (2.04, 0), 0: (2.0, 2.0), 1: (2.04, -2.0), 2: (4.0, 0)}
    g = graph_from(pos, [("s", "j1"), ("j1", "j2"), ("j1", 0), ("j2", 1), ("j2", 2)])
    apart = solve_ppcp(g, "s", [0, 1, 2], method="heuristic")
    assert [_counts(tp) for tp in apart.turning_points] == [[1, 2], [1, 1]]
    merged = solve_ppcp(g, "s", [0, 1, 2], method="heuristic", tp_merge_tol=0.1)
    assert len(merged.turning_points) == 1
    tp = merged.turning_points[0]
    assert tp.position == (2.0, 0.0) and _counts(tp) == [1, 1, 1] and tp.robots == (0, 3)
    _check_blocks(merged)
    # below the tolerance's reach (TPs 0.5 m apart) nothing merges
    far = {**pos, "j2": (2.5, 0), 1: (2.5, -2.0)}
    g2 = graph_from(far, [("s", "j1"), ("j1", "j2"), ("j1", 0), ("j2", 1), ("j2", 2)])
    assert len(solve_ppcp(g2, "s", [0, 1, 2], method="heuristic", tp_merge_tol=0.1).turning_points) == 2
