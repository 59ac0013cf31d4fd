"""Property tests on random graphs: coverage, costs, tree blocks, exact optimality (brute force)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from planning_graphs import brute_min_robots, brute_minmax, random_graph

from parcover_env.planning import exact_min_robots, exact_minmax, metric_closure, solve_ppcp
from parcover_env.planning.exact import route_cost


def _instance(seed: int, n_nodes: int, n_kpois: int, extra: int):
    rng = np.random.default_rng(seed)
    g = random_graph(rng, n_nodes, extra)
    kpois = [int(k) for k in rng.choice(np.arange(1, n_nodes), size=n_kpois, replace=False)]
    return g, kpois


def _check_plan(g, kpois, plan):
    n = len(kpois)
    credited = sorted(k for rp in plan.robots for k in rp.kpois)
    assert credited == list(range(n)), "every KPOI credited to exactly one robot"
    start = np.asarray(g.nodes[0]["pos"])
    for rp in plan.robots:
        np.testing.assert_allclose(rp.path[0], start)
        assert rp.cost <= plan.c_p + 1e-9
        assert rp.length <= rp.cost + 1e-6
        assert list(rp.kpoi_distance) == sorted(rp.kpoi_distance)
        for k, d in zip(rp.kpois, rp.kpoi_distance, strict=False):
            # the credited robot's path passes the KPOI's node at that distance
            node_pos = np.asarray(g.nodes[kpois[k]]["pos"])
            seg = np.linalg.norm(np.diff(rp.path, axis=0), axis=1)
            arc = np.concatenate([[0.0], np.cumsum(seg)])
            i = int(np.argmin(np.abs(arc - d)))
            np.testing.assert_allclose(rp.path[i], node_pos, atol=1e-9)
    assert plan.c_p >= plan.c_max - 1e-9
    for tp in plan.turning_points:
        ranges = sorted(b.robots for b in tp.branches)
        assert ranges[0][0] == tp.robots[0] and ranges[-1][1] == tp.robots[1]
        assert all(a[1] == b[0] for a, b in zip(ranges[:-1], ranges[1:], strict=False))
        for i in range(*tp.robots):
            assert tp.node in plan.robots[i].tree_nodes


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), n_nodes=st.integers(3, 14), extra=st.integers(0, 6), data=st.data())
def test_heuristic_plans_are_valid(seed, n_nodes, extra, data):
    n_kpois = data.draw(st.integers(1, min(7, n_nodes - 1)))
    g, kpois = _instance(seed, n_nodes, n_kpois, extra)
    plan = solve_ppcp(g, 0, kpois, method="heuristic")
    _check_plan(g, kpois, plan)
    assert plan.c_p == pytest.approx(plan.c_max)
    assert plan.r <= plan.n_leaves
    r = data.draw(st.integers(1, n_kpois + 1))
    fixed = solve_ppcp(g, 0, kpois, n_robots=r, method="heuristic")
    _check_plan(g, kpois, fixed)
    assert fixed.r == r


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6), n_nodes=st.integers(4, 12), extra=st.integers(0, 5), data=st.data())
def test_exact_is_minimal_and_never_worse_than_heuristic(seed, n_nodes, extra, data):
    n_kpois = data.draw(st.integers(1, min(6, n_nodes - 1)))
    g, kpois = _instance(seed, n_nodes, n_kpois, extra)
    D = metric_closure(g, 0, kpois).D
    c_max = float(D[0, 1:].max())
    r_exact, routes = exact_min_robots(D, c_max)
    assert sorted(k for rt in routes for k in rt) == list(range(n_kpois))
    assert all(route_cost(D, rt) <= c_max + 1e-9 for rt in routes)
    assert r_exact == brute_min_robots(D, c_max)
    heur = solve_ppcp(g, 0, kpois, method="heuristic")
    assert r_exact <= heur.r
    best = solve_ppcp(g, 0, kpois, method="exact")
    _check_plan(g, kpois, best)
    assert best.r == r_exact
    r = data.draw(st.integers(1, n_kpois))
    c_p, mm = exact_minmax(D, r)
    assert len(mm) <= r and c_p == pytest.approx(brute_minmax(D, r))
    assert solve_ppcp(g, 0, kpois, n_robots=r, method="heuristic").c_p >= c_p - 1e-9
