"""Route progress pinned on hand-built routes the other progress tests leave open: the defaults
(lookahead 0.4 m, window 1 m), a KPOI exactly ``kpoi_radius`` from a route vertex, short segments,
one- and two-vertex routes, routes of different lengths, lead-in offsets and integer inputs."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

from parcover_env.scenarios.progress import RouteTracker, step_many

LINE = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]])


def _walk(tracker, *points):
    for p in points:
        xy = np.atleast_2d(np.asarray(p, dtype=float))
        tracker.update(xy, xy, 0.0)
    return tracker


def test_defaults_look_0_4_m_ahead_and_search_1_m_ahead():
    fine = np.column_stack([np.arange(0.0, 5.01, 0.5), np.zeros(11)])  # a vertex every 0.5 m
    t = RouteTracker(np.array([[5.0, 0.0]]), 0.2, [fine], waypoint_tol=0.15)
    assert t.goal(0).tolist() == pytest.approx([0.4, 0.0])
    _walk(t, [1.9, 0.0])  # 1.9 m ahead: the search reaches the segments starting before 1 m only
    assert t.progress.tolist() == [1.0]
    _walk(t, [1.7, 0.0])
    assert t.progress.tolist() == [1.7] and t.goal(0).tolist() == pytest.approx([2.1, 0.0])


def test_a_kpoi_exactly_kpoi_radius_from_a_vertex_must_be_reached_there():
    t = RouteTracker(np.array([[1.0, 0.25], [3.0, 0.0]]), 0.25, [LINE], waypoint_tol=0.15)
    _walk(t, [0.8, 0.0])
    assert t.progress[0] == pytest.approx(0.8)
    assert t.goal(0).tolist() == [1.0, 0.0]  # clamped at the KPOI vertex, not 0.4 m ahead at (1.3, 0)
    _walk(t, [1.6, 0.0])  # past it without reaching it: progress waits at the vertex
    assert t.progress.tolist() == [1.0]
    _walk(t, [1.05, 0.0], [1.6, 0.0])  # reached within 0.15 m: progress moves on
    assert t.progress[0] == pytest.approx(1.6)
    far = RouteTracker(np.array([[1.0, 0.2501], [3.0, 0.0]]), 0.25, [LINE], waypoint_tol=0.15)
    assert _walk(far, [0.8, 0.0], [1.6, 0.0]).progress[0] == pytest.approx(1.6)  # not a KPOI vertex


def test_progress_on_segments_shorter_than_a_metre_is_the_projection():
    short = np.column_stack([np.arange(0.0, 1.21, 0.3), np.zeros(5)])
    t = _walk(RouteTracker(np.array([[1.2, 0.0]]), 0.1, [short], waypoint_tol=0.1), [0.45, 0.1])
    assert t.progress[0] == pytest.approx(0.45) and t.waypoint.tolist() == [2]
    assert t.remaining(np.array([[0.45, 0.1]]))[0] == pytest.approx(np.hypot(0.4, 0.1) + 0.35)


def test_two_and_one_vertex_routes():
    routes = [np.array([[0.0, 0.0], [2.0, 0.0]]), np.array([[5.0, 5.0]]), np.array([[0.0, 1.0], [0.5, 1.0]])]
    t = RouteTracker(np.array([[9.0, 9.0]]), 0.1, routes, waypoint_tol=0.1)
    xy = np.array([[0.0, 0.0], [4.0, 5.0], [0.0, 1.0]])
    assert t.remaining(xy).tolist() == pytest.approx([2.0, 1.0, 0.5])  # the route's length; to the lone vertex
    np.testing.assert_allclose(t.goals(), [[0.4, 0.0], [5.0, 5.0], [0.4, 1.0]], atol=1e-12)
    _walk(t, *([[x, 0.0], [5.0, 5.0], [0.6, 1.0]] for x in (1.0, 2.0, 3.0)))  # past the ends
    np.testing.assert_allclose(t.goals(), [[2.0, 0.0], [5.0, 5.0], [0.5, 1.0]], atol=1e-12)
    assert t.goal(1).tolist() == [5.0, 5.0] and t.goal(2).tolist() == pytest.approx([0.5, 1.0])
    assert t.remaining(np.array([[2.0, 0.0], [5.0, 5.0], [0.5, 1.0]])).tolist() == pytest.approx([0.0, 0.0, 0.0])


def test_plan_progress_subtracts_the_lead_in():
    t = _walk(RouteTracker(np.array([[3.0, 0.0]]), 0.1, [LINE], waypoint_tol=0.1), [0.5, 0.0])
    assert t.plan_progress.tolist() == pytest.approx([0.5]) and t.offsets.tolist() == [0.0]
    t = _walk(RouteTracker(np.array([[3.0, 0.0]]), 0.1, [LINE], waypoint_tol=0.1, offsets=np.array([0.25])),
              [0.5, 0.0])
    assert t.plan_progress.tolist() == pytest.approx([0.25])


def test_integer_kpois_routes_and_positions_are_the_float_ones():
    ints = RouteTracker([[1, 0], [3, 0]], 1, [[[0, 0], [1, 0], [3, 0]]], waypoint_tol=1)
    floats = RouteTracker(np.array([[1.0, 0.0], [3.0, 0.0]]), 1.0, [LINE], waypoint_tol=1.0)
    n_int = step_many([ints], np.array([[[1, 0]]]), np.array([[[1, 0]]]), [2])
    n_float = step_many([floats], np.array([[[1.0, 0.0]]]), np.array([[[1.0, 0.0]]]), [2.0])
    assert n_int.n_new.dtype == np.int64 and n_int.n_new.tolist() == [1]
    for a, b in zip(n_int, n_float, strict=True):
        assert np.array_equal(a, b)
    assert ints.progress.tolist() == floats.progress.tolist() == [1.0] and ints.visit_time.tolist()[0] == 2.0
    assert ints.remaining([[1, 0]]).tolist() == floats.remaining(np.array([[1.0, 0.0]])).tolist()


def test_an_update_writes_the_state_arrays_in_place_and_copies_own_theirs():
    from parcover_env.scenarios.progress import STATE

    t = RouteTracker(np.array([[3.0, 0.0]]), 0.1, [LINE], waypoint_tol=0.1)
    held = [getattr(t, name) for name in STATE]
    _walk(t, [0.75, 0.0])
    assert all(getattr(t, name) is a for name, a in zip(STATE, held, strict=True))  # never rebound
    assert t.progress.tolist() == [0.75]
    for c in (copy.deepcopy(t), pickle.loads(pickle.dumps(t))):
        assert c.progress.tolist() == [0.75] and not np.shares_memory(c.progress, t.progress)


def test_route_table_pads_every_route_to_the_longest_repeating_its_last_vertex():
    routes = [np.array([[0.0, 0.0], [2.0, 0.0]]), np.array([[5.0, 5.0]])]
    table = RouteTracker(np.array([[9.0, 9.0]]), 0.1, routes, waypoint_tol=0.1).table
    assert table.pts.shape == (2, 2, 2) and table.length.tolist() == [2, 1]
    assert table.pts[1].tolist() == [[5.0, 5.0], [5.0, 5.0]] and table.arc[1].tolist() == [0.0, np.inf]
    assert table.arc_end.tolist() == [2.0, 0.0] and table.seg_len[0].tolist() == [2.0]


def test_a_kpoi_vertex_exactly_waypoint_tol_away_is_reached():
    t = _walk(RouteTracker(np.array([[1.0, 0.0], [3.0, 0.0]]), 0.1, [LINE], waypoint_tol=0.25), [0.75, 0.0])
    assert t.progress.tolist() == [1.0] and t.waypoint.tolist() == [2]  # reached: progress moved onto the vertex
    t = _walk(RouteTracker(np.array([[1.0, 0.0], [3.0, 0.0]]), 0.1, [LINE], waypoint_tol=0.2499), [0.75, 0.0])
    assert t.progress.tolist() == [0.75] and t.waypoint.tolist() == [1]
