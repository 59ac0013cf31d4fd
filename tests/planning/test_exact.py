"""Exact solver: known matrices, input validation, 12-KPOI instance."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.planning import exact_min_robots, exact_minmax, held_karp
from parcover_env.planning.exact import route_cost


def _line_matrix(xs):
    pts = np.concatenate([[0.0], xs])
    return np.abs(pts[:, None] - pts[None, :])


def test_points_on_a_line_need_one_robot_per_side():
    D = _line_matrix(np.array([1.0, 2.0, 3.0, -1.0, -2.0]))
    r, routes = exact_min_robots(D, 3.0)
    assert r == 2
    assert sorted(sorted(rt) for rt in routes) == [[0, 1, 2], [3, 4]]
    c_p, routes = exact_minmax(D, 1)
    assert c_p == pytest.approx(2 + 3 + 2)  # go left first (2), then right (2 + 3)


def test_held_karp_best_is_monotone_on_metric_closure():
    rng = np.random.default_rng(3)
    pts = rng.uniform(0, 5, size=(8, 2))
    D = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    best, H, P = held_karp(D)
    for U in range(1, len(best)):
        for k in range(7):
            if U >> k & 1:
                assert best[U ^ (1 << k)] <= best[U] + 1e-9


def test_twelve_kpois_solved():
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 10, size=(13, 2))
    D = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    c_max = D[0, 1:].max()
    r, routes = exact_min_robots(D, c_max)
    assert sorted(k for rt in routes for k in rt) == list(range(12))
    assert all(route_cost(D, rt) <= c_max + 1e-9 for rt in routes)
    c_p, mm = exact_minmax(D, 3)
    assert len(mm) <= 3 and c_p >= c_max - 1e-9


def test_exact_input_validation():
    with pytest.raises(ValueError, match="square"):
        exact_min_robots(np.zeros((2, 3)), 1.0)
    with pytest.raises(ValueError, match="at most"):
        exact_min_robots(np.zeros((20, 20)), 1.0)
    with pytest.raises(ValueError, match="finite"):
        exact_min_robots(np.array([[0, np.inf], [np.inf, 0]]), 1.0)
    with pytest.raises(ValueError, match="deadline"):
        exact_min_robots(_line_matrix(np.array([2.0])), 1.0)
    with pytest.raises(ValueError, match="r must be"):
        exact_minmax(_line_matrix(np.array([2.0])), 0)
