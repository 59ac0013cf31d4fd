"""Route progress of one episode: KPOIs visited, and each robot's progress along its planned route.

:class:`RouteTracker` is one world's tracker; :func:`step_many` (and :func:`update_many`, the part
of it that changes the trackers) and :func:`goals_many` run the trackers of ``K`` worlds of one
mission (the same KPOIs and routes) in one compiled call, world ``k`` getting bit for bit what its
tracker alone would (``RouteTracker.update`` is the one-world call of :func:`update_many`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from parcover_env.geometry.records import record
from parcover_env.scenarios import progress_kernel

__all__ = ["RouteTracker", "RouteTable", "ProgressStep", "STATE", "step_many", "update_many", "goals_many"]


class RouteTable(NamedTuple):
    """Every robot's route padded to the longest one ``M`` (vertices repeat the last one, arc +inf
    past the end), so progress and goals of all robots are computed in one pass."""

    length: np.ndarray
    """``(N,)`` int64 vertices of each route."""
    arc: np.ndarray
    """``(N, M)`` arc length at each vertex (m), +inf past the end."""
    must: np.ndarray
    """``(N, M)`` bool: a KPOI vertex, to be reached before progress moves past it."""
    pts: np.ndarray
    """``(N, M, 2)`` vertices (m)."""
    e: np.ndarray
    """``(N, M - 1, 2)`` segment vectors (m)."""
    ee: np.ndarray
    """``(N, M - 1)`` their squared lengths, at least 1e-12 (m^2)."""
    seg_len: np.ndarray
    """``(N, M - 1)`` their lengths (m)."""
    arc_end: np.ndarray
    """``(N,)`` each route's length (m)."""


class RouteTracker:
    """Routes are polylines ``(M_i, 2)`` (a lead-in from the robot's start place, then its plan path).

    Progress along a route is the arc length of the robot's pose estimate projected onto the route,
    searched only a little behind and ``window`` ahead of the current progress, so it never jumps
    to a later, spatially overlapping leg (out-and-back tours) and never decreases; an estimate
    more than ``max_offset`` from that part of the route makes no progress. A route vertex
    at a KPOI must be reached (within ``waypoint_tol``) before progress moves past it. The robot's
    goal is the route point ``lookahead`` metres beyond its progress (pure-pursuit style), clamped
    at that KPOI vertex and at the route's end. A KPOI is visited when any robot's true centre comes
    within ``kpoi_radius`` of it.
    """

    def __init__(self, kpois: np.ndarray, kpoi_radius: float, routes: list[np.ndarray], waypoint_tol: float,
                 offsets: np.ndarray | None = None, lookahead: float = 0.4, window: float = 1.0,
                 max_offset: float = 1.0):
        self.kpois = np.asarray(kpois, dtype=float)
        self.kpoi_radius = float(kpoi_radius)
        self.routes = [np.asarray(r, dtype=float).reshape(-1, 2) for r in routes]
        self.lookahead = float(lookahead)
        self.rules = record(progress_kernel.PROGRESS_RULES, window=window, tol=waypoint_tol, max_offset=max_offset)
        """``window``, ``tol`` (the waypoint tolerance) and ``max_offset`` (m) as the compiled update reads them."""
        self.offsets = np.zeros(len(self.routes)) if offsets is None else np.asarray(offsets, dtype=float)
        self._arc = []
        self._must = []
        for r in self.routes:
            seg = np.hypot(*np.diff(r, axis=0).T) if len(r) > 1 else np.zeros(0)
            self._arc.append(np.concatenate([[0.0], np.cumsum(seg)]))
            d = np.linalg.norm(r[:, None, :] - self.kpois[None, :, :], axis=-1)
            self._must.append(d.min(axis=1) <= self.kpoi_radius)
        n = len(self.routes)
        self.table = _padded(self.routes, self._arc, self._must)
        """The routes padded for the compiled loops."""
        self.visited = np.zeros(len(self.kpois), dtype=bool)
        self.visit_time = np.full(len(self.kpois), np.nan)
        self.visitor = np.full(len(self.kpois), -1, dtype=np.int64)
        self.progress = np.zeros(n)
        """Arc length reached along each route (m)."""
        self.waypoint = np.ones(n, dtype=np.int64)
        """Index of the next route vertex ahead of each robot (the one it heads for)."""
        self.advanced = np.zeros(n, dtype=bool)
        """Each robot's waypoint moved at the last update."""
        self._goal_cache: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    @property
    def window(self) -> float:
        """Progress is searched this far ahead of the current progress (m)."""
        return float(self.rules[0]["window"])

    @property
    def tol(self) -> float:
        """A KPOI vertex is reached within this distance (m)."""
        return float(self.rules[0]["tol"])

    @property
    def max_offset(self) -> float:
        """An estimate farther than this from the route makes no progress (m)."""
        return float(self.rules[0]["max_offset"])

    @property
    def done(self) -> bool:
        return bool(self.visited.all())

    @property
    def plan_progress(self) -> np.ndarray:
        """Progress along the plan path proper (lead-in excluded), m."""
        return self.progress - self.offsets

    def update(self, true_xy: np.ndarray, est_xy: np.ndarray, time: float) -> int:
        """Mark KPOIs visited and advance progress; returns how many KPOIs were newly visited."""
        xy = np.asarray(true_xy, dtype=float).reshape(1, -1, 2)
        return int(update_many([self], xy, np.asarray(est_xy, dtype=float).reshape(1, -1, 2), [time])[0])

    def _goals(self) -> tuple[np.ndarray, np.ndarray]:
        """Lookahead goal points ``(N, 2)`` and their arc positions ``(N,)``; cached per progress.
        A compiled loop over robots, the same floats as the numpy reference (``tests/references/progress.py``)."""
        c = self._goal_cache
        if c is not None and np.array_equal(c[0], self.progress):
            return c[1], c[2]
        n, t = len(self.routes), self.table
        goal, s = np.empty((n, 2)), np.empty(n)
        progress_kernel.goals(self.progress, self.lookahead, t.length, t.arc, t.must, t.arc_end, t.pts, goal, s)
        self._goal_cache = (self.progress.copy(), goal, s)
        return goal, s

    def goal(self, i: int) -> np.ndarray:
        """Goal point of robot ``i``: the lookahead point on its route."""
        return self._goal(i)[0]

    def _goal(self, i: int) -> tuple[np.ndarray, float]:
        goal, s = self._goals()
        return goal[i].copy(), float(s[i])

    def goals(self) -> np.ndarray:
        """Goal point of every robot ``(N, 2)``: the lookahead point on its route."""
        return self._goals()[0].copy()

    def remaining(self, xy: np.ndarray) -> np.ndarray:
        """Route length left for each robot from ``xy (N, 2)`` (m): to its goal point, then along."""
        g, s = self._goals()
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return np.hypot(g[:, 0] - xy[:, 0], g[:, 1] - xy[:, 1]) + (self.table.arc_end - s)


def _rows(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """The ``(K, ...)`` block of ``K`` per-world arrays: a view of the one array for ``K = 1``, else a copy."""
    return arrays[0][None] if len(arrays) == 1 else np.array(arrays)


STATE = ("visited", "visit_time", "visitor", "progress", "waypoint", "advanced")
"""A tracker's arrays that a step updates: ``visited``, ``visit_time``, ``visitor`` ``(n_kpois,)``,
``progress``, ``waypoint``, ``advanced`` ``(N,)`` (:class:`~parcover_env.scenarios.progress_kernel.TrackerRows`).
Made with the tracker and never rebound: every update writes them in place."""


class ProgressStep(NamedTuple):
    """What :func:`step_many` gives back besides the trackers' new state."""

    n_new: np.ndarray
    """``(K,)`` int: KPOIs newly visited in each world."""
    goals: np.ndarray
    """``(K, N, 2)``: each robot's lookahead goal point at its new progress (:meth:`RouteTracker.goals`)."""
    remaining: np.ndarray
    """``(K, N)``: route length to go from the true positions (m, :meth:`RouteTracker.remaining`)."""


def step_many(trackers: Sequence[RouteTracker], true_xy: np.ndarray, est_xy: np.ndarray, times: Sequence[float],
              state: progress_kernel.TrackerRows | None = None) -> ProgressStep:
    """:meth:`RouteTracker.update` of the trackers of ``K`` worlds of one mission at once (true and
    estimated positions ``(K, N, 2)``, the worlds' ``times (K,)``), then their goals and the route
    length to go from the true positions, in one compiled call. Each tracker's :data:`STATE` arrays are
    updated in place: ``state``, if given, holds them as ``(K, ...)`` blocks whose rows the trackers'
    arrays are (shared rows); else a single tracker's arrays are used as they are, several trackers'
    are gathered and written back."""
    first, k = trackers[0], len(trackers)
    if state is None:
        state = progress_kernel.TrackerRows(**{name: _rows([getattr(t, name) for t in trackers]) for name in STATE})
    else:
        k = 1  # nothing to write back
    out = progress_kernel.StepOut(np.empty(len(trackers), dtype=np.int64), np.empty((*state.progress.shape, 2)),
                                  np.empty(state.progress.shape))
    progress_kernel.step_many(first.kpois, first.kpoi_radius, np.ascontiguousarray(true_xy, dtype=float),
                              np.ascontiguousarray(est_xy, dtype=float), np.asarray(times, dtype=float), state,
                              first.table, first.rules, first.lookahead, out)
    if k > 1:
        for j, tr in enumerate(trackers):
            for name, block in zip(STATE, state, strict=True):
                getattr(tr, name)[...] = block[j]
    return ProgressStep(out.n_new, out.goal, out.remaining)


def update_many(trackers: Sequence[RouteTracker], true_xy: np.ndarray, est_xy: np.ndarray,
                times: Sequence[float]) -> np.ndarray:
    """The trackers' part of :func:`step_many`: the newly visited KPOIs of each world ``(K,)`` int."""
    return step_many(trackers, true_xy, est_xy, times).n_new


def goals_many(trackers: Sequence[RouteTracker]) -> tuple[np.ndarray, np.ndarray]:
    """The lookahead goal points ``(K, N, 2)`` and their arc positions ``(K, N)`` of the trackers of
    ``K`` worlds of one mission (:meth:`RouteTracker.goals`, one compiled call, no cache)."""
    first = trackers[0]
    t = first.table
    return progress_kernel.goals_many(_rows([tr.progress for tr in trackers]), first.lookahead, t.length, t.arc,
                                      t.must, t.arc_end, t.pts)


def _padded(routes: list[np.ndarray], arcs: list[np.ndarray], musts: list[np.ndarray]) -> RouteTable:
    """The :class:`RouteTable` of ``routes`` with their vertices' arc lengths and KPOI flags."""
    n = len(routes)
    m = max([len(r) for r in routes] + [2])
    length = np.array([len(r) for r in routes], dtype=np.int64)
    pts = np.zeros((n, m, 2))
    arcp = np.full((n, m), np.inf)
    mustp = np.zeros((n, m), dtype=bool)
    for i, (r, arc, must) in enumerate(zip(routes, arcs, musts, strict=True)):
        pts[i, :len(r)] = r
        if len(r):
            pts[i, len(r):] = r[-1]
        arcp[i, :len(r)] = arc
        mustp[i, :len(r)] = must
    e = pts[:, 1:] - pts[:, :-1]
    ee = np.maximum(e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1], 1e-12)
    arc_end = arcp[np.arange(n), np.maximum(length - 1, 0)] if n else np.zeros(0)
    return RouteTable(length, arcp, mustp, pts, e, ee, np.sqrt(ee), arc_end)
