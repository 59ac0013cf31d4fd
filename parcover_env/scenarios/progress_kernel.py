"""Compiled (numba) bodies of :class:`parcover_env.scenarios.progress.RouteTracker` (KPOI visits,
progress, goals), public so that tests and other rooms may use them. Robot by robot, the same IEEE
operations in the same order as the vectorized numpy reference (``tests/references/progress.py``;
a test compares them), no fast-math: the same floats. The routes are the padded tables of
:class:`~parcover_env.scenarios.progress.RouteTable`; the constants a :data:`PROGRESS_RULES` record.
The ``*_many`` kernels run the same bodies over ``K`` worlds of one mission (leading axis ``K``):
world ``k``'s result is the one-world kernel's on its rows, bit for bit.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["PROGRESS_RULES", "advance_all", "advance_many", "goals", "goals_many", "visits", "visits_many",
           "step_many", "TrackerRows", "StepOut"]

PROGRESS_RULES = np.dtype([
    ("window", "f8"),  # progress is searched this far ahead of the current progress (m)
    ("tol", "f8"),  # a KPOI vertex is reached within this distance (m)
    ("max_offset", "f8"),  # an estimate farther than this from the route makes no progress (m)
])
"""The constants of :func:`advance_all` (a record, :mod:`parcover_env.geometry.records`)."""


@njit(cache=True)
def advance_all(p, progress, waypoint, length, arc, must, pts, e, ee, seg_len, rules):
    """New ``(progress, waypoint)`` of every robot from its estimate ``p (N, 2)``, its route's
    ``length``, ``arc``, ``must``, ``pts``, ``e``, ``ee`` and ``seg_len``
    (:class:`~parcover_env.scenarios.progress.RouteTable`) and the :data:`PROGRESS_RULES` record
    ``rules``; see :class:`~parcover_env.scenarios.progress.RouteTracker` for the rule."""
    window, tol, max_offset = rules[0].window, rules[0].tol, rules[0].max_offset
    n, m = arc.shape
    new_progress = progress.copy()
    new_waypoint = waypoint.copy()
    cand = np.empty(m, dtype=np.bool_)
    for i in range(n):
        short = length[i] < 2
        if short:
            new_waypoint[i] = 0
        s0 = progress[i]
        limit = s0 + window
        for j in range(m):
            cand[j] = must[i, j] and arc[i, j] > s0 + 1e-9
        active = not short
        while active:  # the first must-reach vertex ahead bounds the search unless the robot is at it
            j = -1
            for jj in range(m):
                if cand[jj]:
                    j = jj
                    break
            if j < 0:
                break
            aj = arc[i, j]
            if aj > limit:
                break
            if np.hypot(pts[i, j, 0] - p[i, 0], pts[i, j, 1] - p[i, 1]) <= tol:
                s0 = aj  # reached: progress moves past it
                limit = s0 + window
                cand[j] = False
            else:
                limit = aj
                break
        if short:
            continue
        back = s0 - 0.2
        lo = 0
        hi = 0
        for j in range(m):
            if arc[i, j] <= back:
                lo += 1
            if arc[i, j] < limit:
                hi += 1
        lo = max(lo - 1, 0)
        hi = min(hi, length[i] - 1)
        best = math.inf
        bj = 0
        bu = 0.0
        bdist = 0.0
        # segment 0 is always taken first; outside [lo, hi) a segment scores +inf and never wins after it
        for k in range(max(hi, 1)):
            if 0 < k < lo:
                continue
            qx = p[i, 0] - pts[i, k, 0]
            qy = p[i, 1] - pts[i, k, 1]
            u = min(max((qx * e[i, k, 0] + qy * e[i, k, 1]) / ee[i, k], 0.0), 1.0)
            dist = np.hypot(pts[i, k, 0] + u * e[i, k, 0] - p[i, 0], pts[i, k, 1] + u * e[i, k, 1] - p[i, 1])
            score = dist - 1e-6 * (k - lo) if lo <= k < hi else math.inf  # ties: the later segment
            if k == 0 or score < best:
                best, bj, bu, bdist = score, k, u, dist
        new_progress[i] = s0
        if bdist <= max_offset:  # far off the route (lost estimate): no progress
            s = min(arc[i, bj] + bu * seg_len[i, bj], limit)
            s = max(s0, s)
            new_progress[i] = s
            count = 0
            for j in range(m):
                if arc[i, j] <= s + 1e-9:
                    count += 1
            new_waypoint[i] = min(count, length[i] - 1)
    return new_progress, new_waypoint


@njit(cache=True, nogil=True, error_model="numpy")
def goals(progress, lookahead, length, arc, must, arc_end, pts, goal, s_out):
    """Lookahead goal points ``goal (N, 2)`` and their arc positions ``s_out (N,)`` (the rule of
    :meth:`~parcover_env.scenarios.progress.RouteTracker._goals`, robot by robot)."""
    n, m = arc.shape
    for i in range(n):
        prog = progress[i]
        s = prog + lookahead
        for j in range(m):  # the first must-reach vertex ahead bounds the lookahead
            if must[i, j] and arc[i, j] > prog + 1e-9:
                s = min(s, arc[i, j])
                break
        s = min(s, arc_end[i])
        count = 0
        for j in range(m):
            if arc[i, j] <= s:
                count += 1
        k = max(min(count - 1, length[i] - 2), 0)
        if length[i] == 1:
            goal[i, 0] = pts[i, 0, 0]
            goal[i, 1] = pts[i, 0, 1]
            s_out[i] = 0.0
            continue
        seg = arc[i, k + 1] - arc[i, k]
        u = 0.0 if seg <= 0 else (s - arc[i, k]) / seg
        for c in range(2):
            goal[i, c] = pts[i, k, c] + u * (pts[i, k + 1, c] - pts[i, k, c])
        s_out[i] = s


@njit(cache=True, nogil=True)
def visits(kpois, xy, radius, time, visited, visit_time, visitor):
    """Mark the KPOIs ``kpois (K, 2)`` not yet ``visited`` that a point of ``xy (N, 2)`` is within
    ``radius`` of (Euclidean distance ``sqrt(dx^2 + dy^2)``): ``visit_time = time`` and ``visitor`` =
    the nearest such point (the lowest index on ties). Returns how many were newly visited."""
    n_new = 0
    reach = radius * (1.0 + 1e-9)  # a point farther than this along x or y is farther than radius, rounding and all
    for k in range(kpois.shape[0]):
        if visited[k]:
            continue
        best = np.inf
        who = -1
        for i in range(xy.shape[0]):
            dx = kpois[k, 0] - xy[i, 0]
            dy = kpois[k, 1] - xy[i, 1]
            if abs(dx) > reach or abs(dy) > reach:  # skips the square root only (NaN is not skipped)
                continue
            d = math.sqrt(dx * dx + dy * dy)
            if d <= radius and d < best:
                best = d
                who = i
        if who >= 0:
            visited[k] = True
            visit_time[k] = time
            visitor[k] = who
            n_new += 1
    return n_new


@njit(cache=True)
def advance_many(p, progress, waypoint, length, arc, must, pts, e, ee, seg_len, rules):
    """:func:`advance_all` of ``K`` worlds sharing the routes: estimates ``p (K, N, 2)``, state
    ``progress, waypoint (K, N)``; returns the new ``(progress, waypoint)`` ``(K, N)``."""
    new_progress, new_waypoint = progress.copy(), waypoint.copy()
    for k in range(p.shape[0]):
        new_progress[k], new_waypoint[k] = advance_all(p[k], progress[k], waypoint[k], length, arc, must, pts, e, ee,
                                                       seg_len, rules)
    return new_progress, new_waypoint


@njit(cache=True, nogil=True, error_model="numpy")
def goals_many(progress, lookahead, length, arc, must, arc_end, pts):
    """:func:`goals` of ``K`` worlds sharing the routes: ``progress (K, N)`` -> goal points ``(K, N, 2)``
    and their arc positions ``(K, N)``."""
    k_worlds, n = progress.shape
    goal, s_out = np.empty((k_worlds, n, 2)), np.empty((k_worlds, n))
    for k in range(k_worlds):
        goals(progress[k], lookahead, length, arc, must, arc_end, pts, goal[k], s_out[k])
    return goal, s_out


@njit(cache=True, nogil=True)
def visits_many(kpois, xy, radius, time, visited, visit_time, visitor):
    """:func:`visits` of ``K`` worlds sharing the KPOIs: points ``xy (K, N, 2)``, ``time (K,)``, state
    ``visited, visit_time, visitor (K, n_kpois)`` updated in place; returns the counts ``(K,)``."""
    n_new = np.zeros(xy.shape[0], dtype=np.int64)
    for k in range(xy.shape[0]):
        n_new[k] = visits(kpois, xy[k], radius, time[k], visited[k], visit_time[k], visitor[k])
    return n_new


class TrackerRows(NamedTuple):
    """The trackers' state of ``K`` worlds as :func:`step_many` reads and updates it, in place."""

    visited: np.ndarray
    """``(K, n_kpois)`` bool."""
    visit_time: np.ndarray
    """``(K, n_kpois)`` (s, NaN: not yet)."""
    visitor: np.ndarray
    """``(K, n_kpois)`` int64 (-1: none)."""
    progress: np.ndarray
    """``(K, N)`` (m)."""
    waypoint: np.ndarray
    """``(K, N)`` int64."""
    advanced: np.ndarray
    """``(K, N)`` bool: written, the waypoint moved this step."""


class StepOut(NamedTuple):
    """What :func:`step_many` writes besides the trackers' state (the caller's arrays)."""

    n_new: np.ndarray
    """``(K,)`` int64: KPOIs newly visited."""
    goal: np.ndarray
    """``(K, N, 2)``: the lookahead goal points at the new progress."""
    remaining: np.ndarray
    """``(K, N)``: the route length to go from the true positions (m)."""


@njit(cache=True)
def step_many(kpois, radius, true_xy, est_xy, time, state, table, rules, lookahead, out):
    """One step of the trackers of ``K`` worlds sharing the KPOIs and routes (``table``: a
    :class:`~parcover_env.scenarios.progress.RouteTable`; ``state``: :class:`TrackerRows`, updated in
    place): :func:`visits` at the true positions ``true_xy (K, N, 2)`` at ``time (K,)``, :func:`advance_all`
    from the estimates ``est_xy``, then :func:`goals` at the new progress and the route length to go from
    ``true_xy`` (``hypot`` to the goal point, then along: ``arc_end - s``), written into ``out`` (a
    :class:`StepOut`)."""
    t = table
    k_worlds, n = state.progress.shape
    s = np.empty(n)
    for k in range(k_worlds):
        out.n_new[k] = visits(kpois, true_xy[k], radius, time[k], state.visited[k], state.visit_time[k],
                              state.visitor[k])
        progress, waypoint = advance_all(est_xy[k], state.progress[k], state.waypoint[k], t.length, t.arc, t.must,
                                         t.pts, t.e, t.ee, t.seg_len, rules)
        for i in range(n):
            state.advanced[k, i] = waypoint[i] != state.waypoint[k, i]
            state.progress[k, i] = progress[i]
            state.waypoint[k, i] = waypoint[i]
        goals(state.progress[k], lookahead, t.length, t.arc, t.must, t.arc_end, t.pts, out.goal[k], s)
        for i in range(n):
            out.remaining[k, i] = (math.hypot(out.goal[k, i, 0] - true_xy[k, i, 0],
                                              out.goal[k, i, 1] - true_xy[k, i, 1]) + (t.arc_end[i] - s[i]))
