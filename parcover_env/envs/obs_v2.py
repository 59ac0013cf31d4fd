"""Observation version 2's ``route`` and ``teammates`` entries, for all robots of all worlds at once.

What a robot needs to decide to drive, wait, follow or split (see the entries' meanings in
:data:`~parcover_env.envs.obs_spec.ENTRIES`): its target KPOI (the next KPOI of its own route not yet
visited), whether its work is done (``done_mask``), a preview of its route, the next turning point
(TP) of its route with the group arriving there and the branches leaving it, its group size and the
``k`` nearest teammates. Everything is in the robot's frame from the pose estimates (the teammates'
estimates are shared by radio, as the Kinect system shares fixes), never from the true poses.

numpy over ``(K, N)`` arrays: element-wise IEEE operations only (headings' cos/sin from libm), so
world ``k`` of a batch gets the same bits as a separate env.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from parcover_env.envs.obs_spec import N_PREVIEW
from parcover_env.planning.plan import Plan
from parcover_env.sim.contract import StepWorld

__all__ = ["RouteFacts", "TeamRows", "route_facts", "team_rows", "group_sizes", "target_kpois", "fill"]


class RouteFacts(NamedTuple):
    """A mission's static route facts, per robot ``N`` (built once by :func:`route_facts`)."""

    own: np.ndarray
    """``(N, J)`` int64: each robot's own KPOIs in route order (the plan credits it with them), -1 padded."""
    end: np.ndarray
    """``(N, 2)`` each route's last vertex (the target of a robot without KPOIs)."""
    pts: np.ndarray
    """``(N, M, 2)`` route vertices, padded with the last one (the tracker's route table)."""
    length: np.ndarray
    """``(N,)`` int64 vertices of each route."""
    kpois: np.ndarray
    """``(n_kpois, 2)`` KPOI positions (m)."""
    tp_dist: np.ndarray
    """``(N, T)`` plan-path distance of each TP on the robot's route, ascending, +inf padded (m)."""
    tp_xy: np.ndarray
    """``(N, T, 2)`` those TPs' positions (m)."""
    tp_counts: np.ndarray
    """``(N, T, 3)`` robots arriving together, branches with robots, robots on this robot's branch."""


class TeamRows(NamedTuple):
    """The dynamic inputs of :func:`fill`, stacked over ``K`` worlds (by :func:`team_rows`)."""

    est: np.ndarray
    """``(K, N, 3)`` pose estimates."""
    velocity: np.ndarray
    """``(K, N, 2)`` encoder ``(v, omega)``."""
    leader: np.ndarray
    """``(K, N)`` bool."""
    group_size: np.ndarray
    """``(K, N)`` robots in each robot's group."""
    waypoint: np.ndarray
    """``(K, N)`` int64 index of the next route vertex (the route tracker's)."""
    plan_progress: np.ndarray
    """``(K, N)`` progress along the plan path (m)."""
    visited: np.ndarray
    """``(K, n_kpois)`` bool."""


def route_facts(plan: Plan, pts: np.ndarray, length: np.ndarray, kpois: np.ndarray) -> RouteFacts:
    """The :class:`RouteFacts` of ``plan`` with its route table's padded vertices ``pts (N, M, 2)``
    and vertex counts ``length (N,)`` (``RouteTracker.table``) and the KPOIs ``(n_kpois, 2)``."""
    n = plan.r
    own = np.full((n, max([len(r.kpois) for r in plan.robots] + [1])), -1, dtype=np.int64)
    tps: list[list] = [[] for _ in range(n)]
    for i, r in enumerate(plan.robots):
        own[i, :len(r.kpois)] = r.kpois
    for tp in plan.turning_points:
        lo, hi = tp.robots
        branches = [b for b in tp.branches if b.n_robots > 0]
        for i in range(lo, hi):
            mine = next((b.n_robots for b in branches if b.robots[0] <= i < b.robots[1]), 0)
            tps[i].append((tp.distance, *tp.position, hi - lo, len(branches), mine))
    t = max([len(x) for x in tps] + [1])
    table = np.zeros((n, t, 6))
    table[:, :, 0] = np.inf
    for i, rows in enumerate(tps):
        if rows:
            table[i, :len(rows)] = sorted(rows)
    ends = pts[np.arange(n), np.maximum(length - 1, 0)]
    return RouteFacts(own, ends, pts, length, np.asarray(kpois, dtype=float), table[:, :, 0], table[:, :, 1:3],
                      table[:, :, 3:6])


def team_rows(worlds: Sequence[StepWorld]) -> TeamRows:
    """The :class:`TeamRows` of the worlds (through their public ``estimator``, ``team`` and
    ``progress``)."""
    sizes = []
    for w in worlds:
        size = np.zeros(w.team.n)
        for lo, hi in w.team.groups:
            size[lo:hi] = hi - lo
        sizes.append(size)
    return TeamRows(np.stack([w.estimator.estimate for w in worlds]), np.stack([w.estimator.velocity for w in worlds]),
                    np.stack([w.team.leader for w in worlds]), np.stack(sizes),
                    np.stack([w.progress.waypoint for w in worlds]),
                    np.stack([w.progress.plan_progress for w in worlds]),
                    np.stack([w.progress.visited for w in worlds]))


def group_sizes(leader: np.ndarray) -> np.ndarray:
    """``(K, N)`` float: the robots in each robot's group from the worlds' leader flags ``(K, N)`` (a
    team's groups are contiguous, each led by its first robot: a group runs from a leader to the next)."""
    k, n = leader.shape
    group = np.cumsum(leader, axis=1) - 1 + n * np.arange(k)[:, None]  # numbered over all worlds
    return np.bincount(group.ravel(), minlength=k * n)[group].astype(float)


def target_kpois(facts: RouteFacts, visited: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each robot's target KPOI position ``(K, N, 2)`` (its next own KPOI not yet visited, the last
    one once all are; its route's end if it has none) and whether all its own KPOIs are visited
    ``(K, N)`` bool, from the visited flags ``(K, n_kpois)``."""
    own = facts.own
    seen = np.where(own >= 0, visited[:, np.maximum(own, 0)], True)  # (K, N, J)
    done = seen.all(axis=-1)
    pick = np.where(done, np.maximum((own >= 0).sum(axis=1) - 1, 0), np.argmax(~seen, axis=-1))
    idx = own[np.arange(own.shape[0]), pick]  # (K, N)
    xy = np.where((idx >= 0)[..., None], facts.kpois[np.maximum(idx, 0)], facts.end)
    return xy, done


def _frame(est: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin ``(K, N)`` of the estimated headings (libm, element by element)."""
    th = est[..., 2]
    c = np.array([math.cos(t) for t in th.ravel()]).reshape(th.shape)
    s = np.array([math.sin(t) for t in th.ravel()]).reshape(th.shape)
    return c, s


def _rot(c: np.ndarray, s: np.ndarray, dx: np.ndarray, dy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World vectors ``(dx, dy)`` in the frame of heading ``(c, s)`` (x ahead, y left)."""
    return c * dx + s * dy, c * dy - s * dx


def fill(obs: np.ndarray, slices: dict[str, slice], facts: RouteFacts, rows: TeamRows, k: int) -> None:
    """Write the version-2 entries present in ``slices`` into ``obs (K, N, D)``; ``k`` teammate slots."""

    def put(name: str, value: np.ndarray) -> None:
        if name in slices:
            obs[..., slices[name]] = value.reshape(obs.shape[:2] + (-1,))

    est = rows.est
    c, s = _frame(est)
    x, y = est[..., 0], est[..., 1]
    target, done = target_kpois(facts, rows.visited)
    tx, ty = _rot(c, s, target[..., 0] - x, target[..., 1] - y)
    dist = np.sqrt(tx * tx + ty * ty)
    far = dist > 1e-9
    safe = np.where(far, dist, 1.0)
    put("own_kpoi_cos", np.where(far, tx / safe, 1.0))
    put("own_kpoi_sin", np.where(far, ty / safe, 0.0))
    put("own_kpoi_dist", dist)
    put("done_mask", done.astype(float))

    n = est.shape[1]
    at = np.minimum(rows.waypoint[..., None] + np.arange(N_PREVIEW), np.maximum(facts.length - 1, 0)[:, None])
    wp = facts.pts[np.arange(n)[:, None], at]  # (K, N, P, 2)
    wx, wy = _rot(c[..., None], s[..., None], wp[..., 0] - x[..., None], wp[..., 1] - y[..., None])
    put("wp_dx", wx)
    put("wp_dy", wy)

    ahead = np.isfinite(facts.tp_dist) & (facts.tp_dist > rows.plan_progress[..., None])  # (K, N, T); inf = padding
    has = ahead.any(axis=-1)
    nxt = np.argmax(ahead, axis=-1)
    tp_xy = facts.tp_xy[np.arange(n), nxt]  # (K, N, 2)
    counts = np.where(has[..., None], facts.tp_counts[np.arange(n), nxt], 0.0)
    px, py = _rot(c, s, tp_xy[..., 0] - x, tp_xy[..., 1] - y)
    put("tp_ahead", has.astype(float))
    put("tp_dx", np.where(has, px, 0.0))
    put("tp_dy", np.where(has, py, 0.0))
    put("tp_group", counts[..., 0])
    put("tp_branches", counts[..., 1])
    put("tp_own_branch", counts[..., 2])
    put("group_size", rows.group_size)
    if k > 0:
        _teammates(put, rows, (c, s), k)


def _teammates(put, rows: TeamRows, frame: tuple[np.ndarray, np.ndarray], k: int) -> None:
    """The ``mate_*`` entries: the ``k`` nearest teammates by estimated distance (ties: lower index),
    zero-padded with mask 0 when the team has fewer than ``k + 1`` robots."""
    c, s = frame
    est, n = rows.est, rows.est.shape[1]
    dx = est[:, None, :, 0] - est[:, :, None, 0]  # (K, i, j): j seen from i
    dy = est[:, None, :, 1] - est[:, :, None, 1]
    d2 = dx * dx + dy * dy
    d2[:, np.arange(n), np.arange(n)] = np.inf
    m = min(k, n - 1)
    order = np.argsort(d2, axis=-1, kind="stable")[..., :m]  # (K, N, m): j of each slot
    kk, ii = np.arange(len(est))[:, None, None], np.arange(n)[None, :, None]
    ci, si = c[..., None], s[..., None]
    cj, sj, v = c[kk, order], s[kk, order], rows.velocity[..., 0]
    rx, ry = _rot(ci, si, dx[kk, ii, order], dy[kk, ii, order])
    vj = v[kk, order]
    vx, vy = _rot(ci, si, vj * cj - (v * c)[..., None], vj * sj - (v * s)[..., None])
    feats = {"mate_dx": rx, "mate_dy": ry, "mate_cos": cj * ci + sj * si, "mate_sin": sj * ci - cj * si,
             "mate_dvx": vx, "mate_dvy": vy, "mate_leader": rows.leader[kk, order].astype(float),
             "mate_mask": np.ones_like(rx)}
    for name, value in feats.items():
        padded = np.zeros(value.shape[:2] + (k,))
        padded[..., :m] = value
        put(name, padded)
