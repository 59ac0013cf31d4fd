"""Mission bookkeeping: KPOIs visited, each robot's planned route and its current waypoint."""

from __future__ import annotations

import numpy as np

__all__ = ["Mission"]


def _beyond(prev: np.ndarray, a: np.ndarray, b: np.ndarray, p: np.ndarray) -> bool:
    """Whether ``p`` has crossed the corner ``a`` of prev -> a -> b: past the line through ``a``
    normal to the corner's mean direction. Sharp turn-backs (out and back) never count as passed."""
    u_in, u_out = a - prev, b - a
    n_in, n_out = np.hypot(*u_in), np.hypot(*u_out)
    if n_in < 1e-9 or n_out < 1e-9:
        return n_out < 1e-9
    mean = u_in / n_in + u_out / n_out
    return bool(np.hypot(*mean) > 0.5 and float((p - a) @ mean) > 0.0)

class Mission:
    """Routes are polylines ``(M_i, 2)`` (the plan's paths); the goal of robot ``i`` is the next
    waypoint of its route not yet reached (within ``waypoint_tol`` of the robot's pose estimate).
    A KPOI is visited when any robot's true centre comes within ``kpoi_radius`` of it."""

    def __init__(self, kpois: np.ndarray, kpoi_radius: float, routes: list[np.ndarray], waypoint_tol: float):
        self.kpois = np.asarray(kpois, dtype=float)
        self.kpoi_radius = float(kpoi_radius)
        self.routes = [np.asarray(r, dtype=float).reshape(-1, 2) for r in routes]
        self.tol = float(waypoint_tol)
        self.visited = np.zeros(len(self.kpois), dtype=bool)
        self.visit_time = np.full(len(self.kpois), np.nan)
        self.visitor = np.full(len(self.kpois), -1, dtype=np.int64)
        self.waypoint = np.zeros(len(self.routes), dtype=np.int64)
        self.advanced = np.zeros(len(self.routes), dtype=bool)
        # length of each route after each waypoint, for the remaining-distance potential
        self._tail = []
        for r in self.routes:
            seg = np.hypot(*np.diff(r, axis=0).T) if len(r) > 1 else np.zeros(0)
            self._tail.append(np.concatenate([np.cumsum(seg[::-1])[::-1], [0.0]]))

    @property
    def done(self) -> bool:
        return bool(self.visited.all())

    def update(self, true_xy: np.ndarray, est_xy: np.ndarray, time: float) -> int:
        """Mark KPOIs visited and advance waypoints; returns how many KPOIs were newly visited.

        A waypoint is reached when the estimate comes within ``waypoint_tol`` of it, or has passed
        it: within ``3 * waypoint_tol`` of it and beyond it along the next route segment (robots
        in formation cut corners)."""
        d = np.linalg.norm(self.kpois[:, None, :] - true_xy[None, :, :], axis=-1)
        near = d <= self.kpoi_radius
        new = near.any(axis=1) & ~self.visited
        if new.any():
            self.visited |= new
            self.visit_time[new] = time
            self.visitor[new] = np.argmin(np.where(near, d, np.inf), axis=1)[new]
        before = self.waypoint.copy()
        for i, route in enumerate(self.routes):
            k, p = self.waypoint[i], est_xy[i]
            while k < len(route) - 1:
                d = np.hypot(*(route[k] - p))
                prev = route[k - 1] if k > 0 else route[k]
                if not (d < self.tol or (d < 3 * self.tol and _beyond(prev, route[k], route[k + 1], p))):
                    break
                k += 1
            self.waypoint[i] = k
        self.advanced = self.waypoint != before
        return int(new.sum())

    def goals(self) -> np.ndarray:
        """Current waypoint of every robot ``(N, 2)``."""
        return np.array([r[k] for r, k in zip(self.routes, self.waypoint)]).reshape(-1, 2)

    def remaining(self, xy: np.ndarray) -> np.ndarray:
        """Route length left for each robot from ``xy (N, 2)`` (m): to its waypoint, then along."""
        goals = self.goals()
        tail = np.array([t[k] for t, k in zip(self._tail, self.waypoint)])
        return np.hypot(*(goals - xy).T) + tail
