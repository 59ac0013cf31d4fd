"""Compiled (numba) pass writing the observation's scalar entries of every robot of ``K`` worlds
(:func:`scalar_entries_many`); import only through :mod:`parcover_env.envs.observations`. The same float
operations, in the same order, as the numpy formulas they replace
(``tests/envs/test_observation_assembly.py`` keeps the reference)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit


class RobotRows(NamedTuple):
    """Per-robot inputs of :func:`scalar_entries` (the first ten fields of
    :class:`~parcover_env.envs.observations.ScalarInputs`)."""

    est: np.ndarray
    vel: np.ndarray
    leader: np.ndarray
    slot: np.ndarray
    fix_age: np.ndarray
    cov: np.ndarray
    goals: np.ndarray
    rel_xy: np.ndarray
    rel_heading: np.ndarray
    visible: np.ndarray


@njit(cache=True, nogil=True)
def _put(out, i, col, value):
    if col >= 0:
        out[i, col] = value


@njit(cache=True, nogil=True)
def scalar_entries(out, cols, r, slot_div, max_fix_age, kpois, time):
    """Write the non-sensor entries of every robot's observation row ``out (N, D)``: ``cols`` a
    one-element :data:`~parcover_env.envs.obs_spec.KERNEL_COLUMNS` record (each entry's column by
    name, -1 = absent), ``r`` the :class:`RobotRows`, slots divided by ``slot_div``, fix ages capped
    at ``max_fix_age``, and the team's ``kpois`` and ``time`` fractions."""
    col = cols[0]
    for i in range(out.shape[0]):
        th = r.est[i, 2]
        a, b, c = r.cov[i, 0, 0], r.cov[i, 0, 1], r.cov[i, 1, 1]
        mean = 0.5 * (a + c)
        half = math.hypot(0.5 * (a - c), b)
        two_a = 0.0 if half <= 1e-9 * mean else math.atan2(2.0 * b, a - c) - 2.0 * th
        gx = r.goals[i, 0] - r.est[i, 0]
        gy = r.goals[i, 1] - r.est[i, 1]
        cr = math.cos(-th)
        sr = math.sin(-th)
        seen = r.visible[i]
        _put(out, i, col.x, r.est[i, 0])
        _put(out, i, col.y, r.est[i, 1])
        _put(out, i, col.cos_theta, math.cos(th))
        _put(out, i, col.sin_theta, math.sin(th))
        _put(out, i, col.v, r.vel[i, 0])
        _put(out, i, col.omega, r.vel[i, 1])
        _put(out, i, col.leader, 1.0 if r.leader[i] else 0.0)
        _put(out, i, col.slot, r.slot[i] / slot_div)
        _put(out, i, col.fix_age, min(r.fix_age[i], max_fix_age))
        _put(out, i, col.sigma_major, math.sqrt(max(mean + half, 0.0)))
        _put(out, i, col.sigma_minor, math.sqrt(max(mean - half, 0.0)))
        _put(out, i, col.sigma_axis_cos2, math.cos(two_a))
        _put(out, i, col.sigma_axis_sin2, math.sin(two_a))
        _put(out, i, col.sigma_heading, math.sqrt(max(r.cov[i, 2, 2], 0.0)))
        _put(out, i, col.goal_dx, cr * gx - sr * gy)
        _put(out, i, col.goal_dy, sr * gx + cr * gy)
        _put(out, i, col.pred_dx, r.rel_xy[i, 0])
        _put(out, i, col.pred_dy, r.rel_xy[i, 1])
        _put(out, i, col.pred_cos, math.cos(r.rel_heading[i]) if seen else 0.0)
        _put(out, i, col.pred_sin, math.sin(r.rel_heading[i]) if seen else 0.0)
        _put(out, i, col.pred_visible, 1.0 if seen else 0.0)
        _put(out, i, col.kpois_visited, kpois)
        _put(out, i, col.time, time)


@njit(cache=True, nogil=True)
def scalar_entries_many(out, cols, r, slot_div, max_fix_age, kpois, time):
    """:func:`scalar_entries` of ``K`` worlds: ``out (K, N, D)``, the :class:`RobotRows` fields
    ``(K, N, ...)``, the team fractions ``kpois`` and ``time`` ``(K,)``."""
    for k in range(out.shape[0]):
        rows = RobotRows(r.est[k], r.vel[k], r.leader[k], r.slot[k], r.fix_age[k], r.cov[k], r.goals[k], r.rel_xy[k],
                         r.rel_heading[k], r.visible[k])
        scalar_entries(out[k], cols, rows, slot_div, max_fix_age, kpois[k], time[k])
