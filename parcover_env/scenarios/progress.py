"""Route progress of one episode: KPOIs visited, and each robot's progress along its planned route."""

from __future__ import annotations

import numpy as np

__all__ = ["RouteTracker"]


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
        self._build_padded()
        self.visited = np.zeros(len(self.kpois), dtype=bool)
        self.visit_time = np.full(len(self.kpois), np.nan)
        self.visitor = np.full(len(self.kpois), -1, dtype=np.int64)
        self.progress = np.zeros(n)
        """Arc length reached along each route (m)."""
        self.waypoint = np.ones(n, dtype=np.int64)
        """Index of the next route vertex ahead of each robot (the one it heads for)."""
        self.advanced = np.zeros(n, dtype=bool)
        self._goal_cache: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def _build_padded(self) -> None:
        """Static route tables padded to the longest route (arc +inf past the end), so progress and
        goals of all robots are computed in one vectorized pass."""
        n = len(self.routes)
        m = max([len(r) for r in self.routes] + [2])
        self._len = np.array([len(r) for r in self.routes], dtype=np.int64)
        self._pts = np.zeros((n, m, 2))
        self._arcp = np.full((n, m), np.inf)
        self._mustp = np.zeros((n, m), dtype=bool)
        for i, (r, arc, must) in enumerate(zip(self.routes, self._arc, self._must, strict=True)):
            self._pts[i, :len(r)] = r
            if len(r):
                self._pts[i, len(r):] = r[-1]
            self._arcp[i, :len(r)] = arc
            self._mustp[i, :len(r)] = must
        e = self._pts[:, 1:] - self._pts[:, :-1]
        self._e = e
        self._ee = np.maximum(e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1], 1e-12)
        self._seg_len = np.sqrt(self._ee)
        self._k = np.arange(m - 1)
        self._rows = np.arange(n)
        self._last = np.maximum(self._len - 1, 0)
        self._arc_end = self._arcp[self._rows, self._last] if n else np.zeros(0)

    @property
    def done(self) -> bool:
        return bool(self.visited.all())

    @property
    def plan_progress(self) -> np.ndarray:
        """Progress along the plan path proper (lead-in excluded), m."""
        return self.progress - self.offsets

    def update(self, true_xy: np.ndarray, est_xy: np.ndarray, time: float) -> int:
        """Mark KPOIs visited and advance progress; returns how many KPOIs were newly visited."""
        from parcover_env.scenarios._progress_kernel import visits

        n_new = visits(self.kpois, np.ascontiguousarray(true_xy, dtype=float), self.kpoi_radius, float(time),
                       self.visited, self.visit_time, self.visitor)
        before = self.waypoint.copy()
        self._advance_all(np.asarray(est_xy, dtype=float))
        self.advanced = self.waypoint != before
        return n_new

    def _advance_all(self, p: np.ndarray) -> None:
        """Advance every robot's progress from its estimate ``p (N, 2)`` (see the class docstring):
        a compiled loop over robots, the same floats as :meth:`_advance_all_numpy`."""
        if len(self.routes) == 0:
            return
        from parcover_env.scenarios._progress_kernel import advance_all

        self.progress, self.waypoint = advance_all(
            np.ascontiguousarray(p, dtype=float), self.progress, self.waypoint, self._len, self._arcp, self._mustp,
            self._pts, self._e, self._ee, self._seg_len, self.window, self.tol, self.max_offset)

    def _advance_all_numpy(self, p: np.ndarray) -> None:
        """:meth:`_advance_all` as vectorized numpy over robots (the reference of the compiled loop)."""
        n = len(self.routes)
        if n == 0:
            return
        rows, arc, length = self._rows, self._arcp, self._len
        short = length < 2
        self.waypoint[short] = 0
        s0 = self.progress.copy()
        limit = s0 + self.window
        # the first must-reach vertex ahead bounds the search unless the robot is at it
        cand = self._mustp & (arc > s0[:, None] + 1e-9)
        active = ~short
        while True:
            active &= cand.any(axis=1)
            if not active.any():
                break
            j = np.argmax(cand, axis=1)
            aj = arc[rows, j]
            beyond = active & (aj > limit)
            active &= ~beyond
            near = np.hypot(*(self._pts[rows, j] - p).T) <= self.tol
            reached = active & near
            s0 = np.where(reached, aj, s0)  # reached: progress moves past it
            limit = np.where(reached, s0 + self.window, limit)
            limit = np.where(active & ~near, aj, limit)
            cand[rows[reached], j[reached]] = False
            active = reached
        self.progress = np.where(short, self.progress, s0)
        lo = np.maximum(np.sum(arc <= (s0 - 0.2)[:, None], axis=1) - 1, 0)
        hi = np.minimum(np.sum(arc < limit[:, None], axis=1), length - 1)
        a, e, ee = self._pts[:, :-1], self._e, self._ee
        q = p[:, None, :] - a
        u = np.clip((q[..., 0] * e[..., 0] + q[..., 1] * e[..., 1]) / ee, 0.0, 1.0)
        dist = np.hypot(*np.moveaxis(a + u[..., None] * e - p[:, None, :], -1, 0))
        k = self._k[None, :]
        window = (k >= lo[:, None]) & (k < hi[:, None])
        score = np.where(window, dist - 1e-6 * (k - lo[:, None]), np.inf)  # ties: the later segment
        j = np.argmin(score, axis=1)
        ok = ~short & (dist[rows, j] <= self.max_offset)  # far off the route (lost estimate): no progress
        s = np.minimum(arc[rows, j] + u[rows, j] * self._seg_len[rows, j], limit)
        self.progress = np.where(ok, np.maximum(s0, s), self.progress)
        wp = np.minimum(np.sum(arc <= (self.progress + 1e-9)[:, None], axis=1), length - 1)
        self.waypoint = np.where(ok, wp, self.waypoint)

    def _goals(self) -> tuple[np.ndarray, np.ndarray]:
        """Lookahead goal points ``(N, 2)`` and their arc positions ``(N,)``; cached per progress.
        A compiled loop over robots, the same floats as :meth:`_goals_numpy`."""
        c = self._goal_cache
        if c is not None and np.array_equal(c[0], self.progress):
            return c[1], c[2]
        from parcover_env.scenarios._progress_kernel import goals

        n = len(self.routes)
        goal, s = np.empty((n, 2)), np.empty(n)
        goals(self.progress, self.lookahead, self._len, self._arcp, self._mustp, self._arc_end, self._pts, goal, s)
        self._goal_cache = (self.progress.copy(), goal, s)
        return goal, s

    def _goals_numpy(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_goals` as vectorized numpy over robots, uncached (the reference of the compiled loop)."""
        rows, arc, prog = self._rows, self._arcp, self.progress
        s = prog + self.lookahead
        ahead = self._mustp & (arc > prog[:, None] + 1e-9)
        first = np.argmax(ahead, axis=1)
        s = np.where(ahead.any(axis=1), np.minimum(s, arc[rows, first]), s)
        s = np.minimum(s, self._arc_end)
        k = np.maximum(np.minimum(np.sum(arc <= s[:, None], axis=1) - 1, self._len - 2), 0)
        seg = arc[rows, k + 1] - arc[rows, k]
        with np.errstate(invalid="ignore", divide="ignore"):
            u = np.where(seg <= 0, 0.0, (s - arc[rows, k]) / np.where(seg <= 0, 1.0, seg))
        pk, pk1 = self._pts[rows, k], self._pts[rows, k + 1]
        goal = pk + u[:, None] * (pk1 - pk)
        single = self._len == 1
        goal[single] = self._pts[single, 0]
        s[single] = 0.0
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
        return np.hypot(g[:, 0] - xy[:, 0], g[:, 1] - xy[:, 1]) + (self._arc_end - s)
