"""Route progress: monotone, never skips a KPOI vertex, no jump across out-and-back legs."""

from __future__ import annotations

import numpy as np

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
