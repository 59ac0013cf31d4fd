"""References of :mod:`parcover_env.scenarios.progress_kernel`: the route-progress rule, the
lookahead goals and the KPOI visits as vectorized numpy over robots."""

from __future__ import annotations

import numpy as np

from parcover_env.scenarios.progress import RouteTracker


def advance_all(tracker: RouteTracker, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~parcover_env.scenarios.progress_kernel.advance_all`: the new ``(progress, waypoint)``
    of every robot of ``tracker`` from its estimate ``p (N, 2)`` (the tracker is not changed)."""
    t, progress, waypoint = tracker.table, tracker.progress.copy(), tracker.waypoint.copy()
    n = len(progress)
    if n == 0:
        return progress, waypoint
    rows, arc, length = np.arange(n), t.arc, t.length
    short = length < 2
    waypoint[short] = 0
    s0 = progress.copy()
    limit = s0 + tracker.window
    # the first must-reach vertex ahead bounds the search unless the robot is at it
    cand = t.must & (arc > s0[:, None] + 1e-9)
    active = ~short
    while True:
        active &= cand.any(axis=1)
        if not active.any():
            break
        j = np.argmax(cand, axis=1)
        aj = arc[rows, j]
        beyond = active & (aj > limit)
        active &= ~beyond
        near = np.hypot(*(t.pts[rows, j] - p).T) <= tracker.tol
        reached = active & near
        s0 = np.where(reached, aj, s0)  # reached: progress moves past it
        limit = np.where(reached, s0 + tracker.window, limit)
        limit = np.where(active & ~near, aj, limit)
        cand[rows[reached], j[reached]] = False
        active = reached
    progress = np.where(short, progress, s0)
    lo = np.maximum(np.sum(arc <= (s0 - 0.2)[:, None], axis=1) - 1, 0)
    hi = np.minimum(np.sum(arc < limit[:, None], axis=1), length - 1)
    a, e, ee = t.pts[:, :-1], t.e, t.ee
    q = p[:, None, :] - a
    u = np.clip((q[..., 0] * e[..., 0] + q[..., 1] * e[..., 1]) / ee, 0.0, 1.0)
    dist = np.hypot(*np.moveaxis(a + u[..., None] * e - p[:, None, :], -1, 0))
    k = np.arange(arc.shape[1] - 1)[None, :]
    window = (k >= lo[:, None]) & (k < hi[:, None])
    score = np.where(window, dist - 1e-6 * (k - lo[:, None]), np.inf)  # ties: the later segment
    j = np.argmin(score, axis=1)
    ok = ~short & (dist[rows, j] <= tracker.max_offset)  # far off the route (lost estimate): no progress
    s = np.minimum(arc[rows, j] + u[rows, j] * t.seg_len[rows, j], limit)
    progress = np.where(ok, np.maximum(s0, s), progress)
    wp = np.minimum(np.sum(arc <= (progress + 1e-9)[:, None], axis=1), length - 1)
    return progress, np.where(ok, wp, waypoint)


def goals(tracker: RouteTracker) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~parcover_env.scenarios.progress_kernel.goals`: the lookahead goal points ``(N, 2)`` and
    their arc positions ``(N,)`` of every robot of ``tracker``."""
    t, prog = tracker.table, tracker.progress
    rows, arc = np.arange(len(prog)), t.arc
    s = prog + tracker.lookahead
    ahead = t.must & (arc > prog[:, None] + 1e-9)
    first = np.argmax(ahead, axis=1)
    s = np.where(ahead.any(axis=1), np.minimum(s, arc[rows, first]), s)
    s = np.minimum(s, t.arc_end)
    k = np.maximum(np.minimum(np.sum(arc <= s[:, None], axis=1) - 1, t.length - 2), 0)
    seg = arc[rows, k + 1] - arc[rows, k]
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(seg <= 0, 0.0, (s - arc[rows, k]) / np.where(seg <= 0, 1.0, seg))
    pk, pk1 = t.pts[rows, k], t.pts[rows, k + 1]
    goal = pk + u[:, None] * (pk1 - pk)
    single = t.length == 1
    goal[single] = t.pts[single, 0]
    s[single] = 0.0
    return goal, s


def visits(kpois: np.ndarray, radius: float, visited: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~parcover_env.scenarios.progress_kernel.visits`: the newly visited KPOIs and their
    visitors, the nearest robot within the radius (lowest index on ties)."""
    d = np.linalg.norm(kpois[:, None, :] - xy[None, :, :], axis=-1)
    near = d <= radius
    new = near.any(axis=1) & ~visited
    return new, np.argmin(np.where(near, d, np.inf), axis=1)
