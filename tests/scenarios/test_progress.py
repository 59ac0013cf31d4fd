"""Route progress: monotone, never skips a KPOI vertex, no jump across out-and-back legs."""

from __future__ import annotations

import numpy as np
from references import progress as reference

from parcover_env.scenarios.progress import RouteTracker as Mission


def test_out_and_back_route_is_followed_leg_by_leg():
    route = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.5], [2.0, 0.0], [4.0, 0.0]])
    kpois = np.array([[2.0, 1.5], [4.0, 0.0]])
    m = Mission(kpois, 0.2, [route], waypoint_tol=0.15, lookahead=0.4)
    # walk to the foot of the spur: the goal is up the spur, not along the later leg
    for x in np.arange(0.0, 2.01, 0.1):
        m.update(np.array([[x, 0.1]]), np.array([[x, 0.1]]), 0.0)
    assert m.goals()[0][1] > 0.1
    # short of the KPOI vertex the goal is clamped on it
    m.update(np.array([[2.0, 1.2]]), np.array([[2.0, 1.2]]), 1.0)
    np.testing.assert_allclose(m.goals()[0], [2.0, 1.5])
    n = m.update(np.array([[2.0, 1.45]]), np.array([[2.0, 1.45]]), 2.0)
    assert n == 1 and m.visited.tolist() == [True, False] and m.visit_time[0] == 2.0
    assert m.goals()[0][1] < 1.5  # now heading back down
    progress = m.progress[0]
    m.update(np.array([[0.0, 0.0]]), np.array([[0.0, 0.0]]), 3.0)  # estimate far off the route: no change
    assert m.progress[0] == progress


def test_remaining_decreases_along_the_route():
    route = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]])
    m = Mission(np.array([[3.0, 3.0]]), 0.2, [route], waypoint_tol=0.15)
    rem = []
    for x, y in [(0.0, 0.0), (1.0, 0.0), (2.5, 0.1), (3.0, 1.0), (3.0, 2.9)]:
        m.update(np.array([[x, y]]), np.array([[x, y]]), 0.0)
        rem.append(m.remaining(np.array([[x, y]]))[0])
    assert all(a > b for a, b in zip(rem, rem[1:])) and rem[0] > 5.9


def test_compiled_progress_is_the_same_floats_as_the_numpy_reference():
    """Robots walking their routes with noisy, sometimes lost estimates, plus a one-vertex route and
    an out-and-back spur: the compiled update equals the vectorized numpy one, float for float."""
    route = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.5], [2.0, 0.0], [4.0, 0.0], [4.0, 2.0]])
    kpois = np.array([[2.0, 1.5], [4.0, 0.0], [4.0, 2.0]])
    short = np.array([[0.0, 3.0], [0.3, 3.0], [0.3, 3.0], [0.45, 3.2], [2.0, 3.2]])  # 0.3 m, 0 m, 0.25 m legs
    routes = [route, route[::-1].copy(), route[:3] + 0.05, short, np.array([[1.0, 1.0]])]
    fast = Mission(kpois, 0.2, routes, waypoint_tol=0.15, lookahead=0.4)
    rng = np.random.default_rng(2)
    arc = [np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(r, axis=0).T))]) for r in routes[:4]]
    moved = 0
    for t in range(300):
        s = t * 0.035  # walk along each route by arc length, with estimate noise and jumps
        est = []
        for r, a in zip(routes[:4], arc, strict=True):
            k = min(np.searchsorted(a, s, side="right") - 1, len(r) - 2)
            u = min((s - a[k]) / (a[k + 1] - a[k]), 1.0) if a[k + 1] > a[k] else 0.0
            est.append(r[k] + u * (r[k + 1] - r[k]))
        est.append([1.0, 1.0])
        est = np.array(est) + rng.normal(0.0, 0.05, (5, 2))
        if t % 37 == 0:
            est[t % 3] += 3.0  # a lost estimate: no progress
        want_progress, want_waypoint = reference.advance_all(fast, est)
        new, _ = reference.visits(kpois, 0.2, fast.visited, est)
        before = fast.waypoint.copy()
        assert fast.update(est, est, 0.1 * t) == new.sum()
        assert fast.progress.tobytes() == want_progress.tobytes()
        assert fast.waypoint.tolist() == want_waypoint.tolist()
        assert fast.advanced.tolist() == (want_waypoint != before).tolist()
        goal, s_goal = reference.goals(fast)
        assert fast.goals().tobytes() == goal.tobytes() and fast._goals()[1].tobytes() == s_goal.tobytes()
        moved += int(fast.advanced.sum())
    assert moved >= 10 and fast.visited.all()  # the walk crossed vertices and reached every KPOI
    assert fast.waypoint[4] == 0 and fast.progress[4] == 0.0


def test_kpoi_visits_are_the_numpy_rule():
    """Random crowds: the same KPOIs newly visited, at the step's time, by the same robots; a robot
    exactly on the radius visits, one just beyond does not; equidistant robots: the lower index."""
    rng = np.random.default_rng(4)
    kpois = rng.uniform(0, 6, (25, 2))
    route = np.array([[0.0, 0.0], [1.0, 0.0]])
    m = Mission(kpois, 0.3, [route] * 6, waypoint_tol=0.15)
    visited = m.visited.copy()
    for t in range(40):
        xy = rng.uniform(0, 6, (6, 2))
        new, who = reference.visits(kpois, 0.3, visited, xy)
        assert m.update(xy, xy, 0.1 * t) == new.sum()
        assert m.visited.tolist() == (visited | new).tolist()
        assert np.array_equal(m.visit_time[new], np.full(new.sum(), 0.1 * t)) and (m.visitor[new] == who[new]).all()
        visited = m.visited.copy()
    assert 5 < visited.sum() < 25
    edge = Mission(np.array([[0.0, 0.0], [5.0, 0.0]]), 0.25, [route] * 3, waypoint_tol=0.15)
    xy = np.array([[0.0, 0.5], [0.0, 0.25], [0.0, -0.25]])  # the last two on the radius, equidistant
    assert edge.update(xy, xy, 2.0) == 1 and edge.visitor.tolist() == [1, -1] and edge.visit_time[0] == 2.0
    beyond = np.array([[5.0, 0.2500001], [5.0, -0.2500001], [9.0, 0.0]])
    assert edge.update(beyond, xy, 3.0) == 0 and not edge.visited[1]
    assert edge.update(xy, xy, 4.0) == 0 and edge.visit_time[0] == 2.0  # visited once, at the first time


def test_advanced_flags_the_robots_whose_waypoint_moved_this_update():
    """``advanced``: True for the robots that passed a route vertex in this update, else False."""
    route = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    m = Mission(np.array([[2.0, 0.0]]), 0.2, [route, route + [0.0, 1.0]], waypoint_tol=0.15)
    still = np.array([[0.0, 0.0], [0.0, 1.0]])
    m.update(still, still, 0.0)
    assert m.advanced.tolist() == [False, False]
    moved = np.array([[1.2, 0.0], [0.0, 1.0]])
    m.update(moved, moved, 0.1)
    assert m.advanced.tolist() == [True, False] and m.waypoint.tolist() == [2, 1]
    m.update(moved, moved, 0.2)
    assert m.advanced.tolist() == [False, False]
