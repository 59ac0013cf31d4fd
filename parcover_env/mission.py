"""Mission bookkeeping: KPOIs visited, and each robot's progress along its planned route."""

from __future__ import annotations

import numpy as np

__all__ = ["Mission"]


class Mission:
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
        self.tol = float(waypoint_tol)
        self.lookahead, self.window, self.max_offset = float(lookahead), float(window), float(max_offset)
        self.offsets = np.zeros(len(self.routes)) if offsets is None else np.asarray(offsets, dtype=float)
        self._arc = []
        self._must = []
        for r in self.routes:
            seg = np.hypot(*np.diff(r, axis=0).T) if len(r) > 1 else np.zeros(0)
            self._arc.append(np.concatenate([[0.0], np.cumsum(seg)]))
            d = np.linalg.norm(r[:, None, :] - self.kpois[None, :, :], axis=-1)
            self._must.append(d.min(axis=1) <= self.kpoi_radius)
        n = len(self.routes)
        self.visited = np.zeros(len(self.kpois), dtype=bool)
        self.visit_time = np.full(len(self.kpois), np.nan)
        self.visitor = np.full(len(self.kpois), -1, dtype=np.int64)
        self.progress = np.zeros(n)
        """Arc length reached along each route (m)."""
        self.waypoint = np.ones(n, dtype=np.int64)
        """Index of the next route vertex ahead of each robot (the one it heads for)."""
        self.advanced = np.zeros(n, dtype=bool)

    @property
    def done(self) -> bool:
        return bool(self.visited.all())

    @property
    def plan_progress(self) -> np.ndarray:
        """Progress along the plan path proper (lead-in excluded), m."""
        return self.progress - self.offsets

    def update(self, true_xy: np.ndarray, est_xy: np.ndarray, time: float) -> int:
        """Mark KPOIs visited and advance progress; returns how many KPOIs were newly visited."""
        d = np.linalg.norm(self.kpois[:, None, :] - true_xy[None, :, :], axis=-1)
        near = d <= self.kpoi_radius
        new = near.any(axis=1) & ~self.visited
        if new.any():
            self.visited |= new
            self.visit_time[new] = time
            self.visitor[new] = np.argmin(np.where(near, d, np.inf), axis=1)[new]
        before = self.waypoint.copy()
        for i in range(len(self.routes)):
            self._advance(i, est_xy[i])
        self.advanced = self.waypoint != before
        return int(new.sum())

    def _advance(self, i: int, p: np.ndarray) -> None:
        route, arc, must = self.routes[i], self._arc[i], self._must[i]
        if len(route) < 2:
            self.waypoint[i] = 0
            return
        s0 = self.progress[i]
        # the first must-reach vertex ahead bounds the search unless the robot is at it
        limit = s0 + self.window
        for j in np.flatnonzero(must & (arc > s0 + 1e-9)):
            if arc[j] > limit:
                break
            if np.hypot(*(route[j] - p)) <= self.tol:  # reached: progress moves past it
                s0 = self.progress[i] = arc[j]
                limit = s0 + self.window
                continue
            limit = arc[j]
            break
        lo = max(int(np.searchsorted(arc, s0 - 0.2, side="right")) - 1, 0)
        hi = min(int(np.searchsorted(arc, limit, side="left")), len(route) - 1)
        a, b = route[lo:hi], route[lo + 1:hi + 1]
        e = b - a
        ee = np.maximum(np.einsum("ij,ij->i", e, e), 1e-12)
        u = np.clip(np.einsum("ij,ij->i", p - a, e) / ee, 0.0, 1.0)
        dist = np.hypot(*(a + u[:, None] * e - p).T)
        j = int(np.argmin(dist - 1e-6 * np.arange(len(dist))))  # ties: the later segment
        if dist[j] > self.max_offset:  # far off the route (e.g. a lost estimate): no progress
            return
        s = min(arc[lo + j] + u[j] * np.sqrt(ee[j]), limit)
        self.progress[i] = max(s0, s)
        self.waypoint[i] = min(int(np.searchsorted(arc, self.progress[i] + 1e-9, side="right")), len(route) - 1)

    def _goal(self, i: int) -> tuple[np.ndarray, float]:
        route, arc, must = self.routes[i], self._arc[i], self._must[i]
        if len(route) == 1:
            return route[0], 0.0
        s = self.progress[i] + self.lookahead
        ahead = np.flatnonzero(must & (arc > self.progress[i] + 1e-9))
        if len(ahead):
            s = min(s, arc[ahead[0]])
        s = min(s, arc[-1])
        k = min(int(np.searchsorted(arc, s, side="right")) - 1, len(route) - 2)
        seg = arc[k + 1] - arc[k]
        u = 0.0 if seg <= 0 else (s - arc[k]) / seg
        return route[k] + u * (route[k + 1] - route[k]), s

    def goals(self) -> np.ndarray:
        """Goal point of every robot ``(N, 2)``: the lookahead point on its route."""
        return np.array([self._goal(i)[0] for i in range(len(self.routes))]).reshape(-1, 2)

    def remaining(self, xy: np.ndarray) -> np.ndarray:
        """Route length left for each robot from ``xy (N, 2)`` (m): to its goal point, then along."""
        out = np.empty(len(self.routes))
        for i in range(len(self.routes)):
            g, s = self._goal(i)
            out[i] = np.hypot(*(g - xy[i])) + (self._arc[i][-1] - s)
        return out
