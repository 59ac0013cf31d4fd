"""Compiled (numba) loops of the mission's step: the formation errors, the episode metrics' sums
(:func:`record_many`) and the test for teams that may split; import only through
:mod:`parcover_env.mission.metrics` and :mod:`parcover_env.mission.team`. The same float
operations, in the same order, as the numpy formulas they replace (``tests/envs/test_values.py``
keeps references). The ``*_many`` loops run a one-world loop over ``K`` worlds (leading axis)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.geometry.angle_kernels import wrap
from parcover_env.geometry.numpy_order import block_sum


@njit(cache=True, nogil=True)
def formation_errors(poses, predecessor, offset, l_d, psi_d, dl, dpsi):
    """``dl[k], dpsi[k]`` of the ``k``-th follower (robot order): ``l - l_d`` and
    ``psi - psi_d`` (unwrapped) with ``l, psi`` the distance and bearing (in the predecessor's frame) of the
    follower's point ``offset`` ahead of its centre, seen from the predecessor; returns the count."""
    k = 0
    for i in range(poses.shape[0]):
        j = predecessor[i]
        if j < 0:
            continue
        qx = poses[i, 0] + offset * math.cos(poses[i, 2])
        qy = poses[i, 1] + offset * math.sin(poses[i, 2])
        dx = qx - poses[j, 0]
        dy = qy - poses[j, 1]
        dl[k] = math.hypot(dx, dy) - l_d
        dpsi[k] = math.atan2(dy, dx) - poses[j, 2] - psi_d  # wrapped by the caller (geometry.wrap_angle)
        k += 1
    return k


@njit(cache=True, nogil=True)
def formation_errors_many(poses, predecessor, offset, l_d, psi_d, dl, dpsi, n):
    """:func:`formation_errors` of ``K`` worlds: ``poses (K, N, 3)``, ``predecessor (K, N)``; writes
    ``dl, dpsi (K, N)`` (world ``k``'s followers in its first ``n[k]`` columns, 0 after) and ``n (K,)``
    (the caller's arrays: a compiled call that returns arrays pays for boxing each one)."""
    dl[...] = 0.0
    dpsi[...] = 0.0
    for k in range(predecessor.shape[0]):
        n[k] = formation_errors(poses[k], predecessor[k], offset, l_d, psi_d, dl[k], dpsi[k])


@njit(cache=True, nogil=True)
def may_split(tp, est, plan_progress, fix, tol, margin, out):
    """Writes ``out (K,)`` bool: some robot ``i`` of world ``k`` heads for a TP (``tp[k, i] = (x, y,
    distance)``, NaN: none) and has passed its distance (``plan_progress[k, i] >= distance - 1e-6``), or
    its estimate ``est[k, i]`` or this step's fix ``fix[k, i]`` (NaN: none) lies within ``tol`` of it;
    every test widened by ``margin``."""
    reach = tol + margin
    for k in range(tp.shape[0]):
        out[k] = False
        for i in range(tp.shape[1]):
            x, y, d = tp[k, i, 0], tp[k, i, 1], tp[k, i, 2]
            if math.isnan(d):
                continue
            if (plan_progress[k, i] >= d - 1e-6 - margin or math.hypot(est[k, i, 0] - x, est[k, i, 1] - y) <= reach
                    or math.hypot(fix[k, i, 0] - x, fix[k, i, 1] - y) <= reach):
                out[k] = True
                break


@njit(cache=True, nogil=True)
def pairwise_sum(a, lo, n):
    """``a[lo:lo + n]`` summed as numpy sums a contiguous float64 run (its pairwise summation: blocks of
    at most 128 values, longer runs halved at a multiple of 8 and the halves' sums added), so the same
    float as ``np.sum``. The halving is walked with an explicit stack (no recursion: numba's cache)."""
    if n <= 128:
        return block_sum(a, lo, n)
    los, ns, stage = np.empty(128, np.int64), np.empty(128, np.int64), np.zeros(128, np.int64)
    vals = np.empty(128)
    top, nv = 0, 0
    los[0], ns[0] = lo, n
    while top >= 0:
        at, m = los[top], ns[top]
        if m <= 128:
            vals[nv] = block_sum(a, at, m)
            nv += 1
            top -= 1
            continue
        half = m // 2
        half -= half % 8
        if stage[top] < 2:  # push the left half, then the right one
            first = stage[top] == 0
            stage[top] += 1
            top += 1
            los[top], ns[top], stage[top] = (at, half, 0) if first else (at + half, m - half, 0)
        else:  # both halves done: left + right
            vals[nv - 2] = vals[nv - 2] + vals[nv - 1]
            nv -= 1
            top -= 1
    return vals[0]


@njit(cache=True, nogil=True)
def path_and_error_sums(before, true, est, paths, sq):
    """Per world of ``K``: adds to the path lengths ``paths (K, N)`` (in place) each robot's straight
    step ``before -> true`` (``(K, N, 3)`` poses; ``hypot``), and writes into ``sq (K,)`` the sum of
    squared position errors of the estimates ``est`` over the world's robots (``np.sum`` of the
    ``(N, 2)`` squared differences)."""
    k_worlds, n = paths.shape
    sq_terms = np.empty(2 * n)
    for k in range(k_worlds):
        for i in range(n):
            paths[k, i] = paths[k, i] + math.hypot(true[k, i, 0] - before[k, i, 0], true[k, i, 1] - before[k, i, 1])
            ex = true[k, i, 0] - est[k, i, 0]
            ey = true[k, i, 1] - est[k, i, 1]
            sq_terms[2 * i] = ex * ex
            sq_terms[2 * i + 1] = ey * ey
        sq[k] = pairwise_sum(sq_terms, 0, 2 * n)


METRIC_TOTALS = ("steps", "time", "kpois_visited", "wall_collisions", "robot_collisions", "sq_err", "n_err", "sq_l",
                 "sq_psi", "n_form", "unseen_leader_time", "makespan")
"""The columns of :func:`record_many`'s ``totals``: :data:`parcover_env.mission.metrics.TOTALS` (a test
keeps them equal)."""
_STEPS, _TIME, _KPOIS, _WALL, _ROBOT, _SQ_ERR, _N_ERR, _SQ_L, _SQ_PSI, _N_FORM, _UNSEEN, _MAKESPAN = range(12)


class MetricsStep(NamedTuple):
    """One step of ``K`` worlds as :func:`record_many` reads it (C-contiguous arrays)."""

    before: np.ndarray
    """``(K, N, 3)`` true poses before the step."""
    true: np.ndarray
    """``(K, N, 3)`` true poses after it."""
    est: np.ndarray
    """``(K, N, 3)`` pose estimates after it."""
    predecessor: np.ndarray
    """``(K, N)`` int64: the robot each robot follows (-1 none)."""
    visited: np.ndarray
    """``(K, M)`` bool: KPOIs visited."""
    visit_time: np.ndarray
    """``(K, M)``: their visit times (s, NaN: not yet)."""
    wall: np.ndarray
    """``(K, N)`` int64: each robot's new wall contacts."""
    robot: np.ndarray
    """``(K, N)`` int64: its new robot contacts (a contact counts for both robots)."""
    unseen: np.ndarray
    """``(K,)`` int64: leaders outside every Kinect footprint."""
    time: np.ndarray
    """``(K,)``: the worlds' times after the step (s)."""


@njit(cache=True, nogil=True)
def record_many(totals, paths, step, formation, control_dt):
    """Adds one step of ``K`` worlds (a :class:`MetricsStep`) to their metrics: ``totals (K, 12)``
    (:data:`METRIC_TOTALS`) and ``paths (K, N)``, in place. Path lengths and the squared position errors
    as :func:`path_and_error_sums`; the followers' squared formation errors (``formation = (offset, l_d,
    psi_d)``, :func:`formation_errors`, ``psi`` wrapped) summed as ``np.sum`` sums them; a robot-robot contact
    counted once (halved); ``control_dt`` per leader out of view; the makespan (the last visit time) on the
    step every KPOI is visited, if not set yet."""
    k_worlds, n = paths.shape
    sq = np.empty(k_worlds)
    path_and_error_sums(step.before, step.true, step.est, paths, sq)
    offset, l_d, psi_d = formation
    dl, dpsi = np.empty(n), np.empty(n)
    for k in range(k_worlds):
        t = totals[k]
        f = formation_errors(step.true[k], step.predecessor[k], offset, l_d, psi_d, dl, dpsi)
        for j in range(f):
            dl[j] = dl[j] * dl[j]
            p = wrap(dpsi[j])
            dpsi[j] = p * p
        wall, robot = 0, 0
        for i in range(n):
            wall += step.wall[k, i]
            robot += step.robot[k, i]
        visited, last = 0, -np.inf
        for j in range(step.visited.shape[1]):
            if step.visited[k, j]:
                visited += 1
            v = step.visit_time[k, j]
            if v > last:  # NaN never is
                last = v
        t[_STEPS] += 1.0
        t[_TIME] = step.time[k]
        t[_KPOIS] = visited
        t[_WALL] += wall
        t[_ROBOT] += robot // 2
        t[_SQ_ERR] += sq[k]
        t[_N_ERR] += n
        if f:
            t[_SQ_L] += pairwise_sum(dl, 0, f)
            t[_SQ_PSI] += pairwise_sum(dpsi, 0, f)
            t[_N_FORM] += f
        if step.unseen[k]:
            t[_UNSEEN] += control_dt * step.unseen[k]
        if visited == step.visited.shape[1] and math.isnan(t[_MAKESPAN]):
            t[_MAKESPAN] = last
