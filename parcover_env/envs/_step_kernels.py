"""Compiled (numba) loops of an env step: the observation's scalar entries and the formation errors;
import only through :mod:`parcover_env.envs.observations` and :mod:`parcover_env.envs.metrics`. The
same float operations, in the same order, as the numpy formulas they replace
(``tests/envs/test_observation_assembly.py`` and ``tests/envs/test_values.py`` keep references)."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True)
def scalar_entries(out, cols, est, vel, leader, slot, slot_div, fix_age, max_fix_age, cov, goals, rel_xy,
                   rel_heading, visible, kpois, time):
    """Write the scalar entries of every robot's observation row ``out (N, D)``; ``cols``: the column
    of each entry of :data:`~parcover_env.envs.observations.SCALAR_ENTRIES` (-1: not in the layout)."""
    for i in range(out.shape[0]):
        th = est[i, 2]
        a, b, c = cov[i, 0, 0], cov[i, 0, 1], cov[i, 1, 1]
        mean = 0.5 * (a + c)
        half = math.hypot(0.5 * (a - c), b)
        two_a = 0.0 if half <= 1e-9 * mean else math.atan2(2.0 * b, a - c) - 2.0 * th
        gx = goals[i, 0] - est[i, 0]
        gy = goals[i, 1] - est[i, 1]
        cr = math.cos(-th)
        sr = math.sin(-th)
        seen = visible[i]
        values = (est[i, 0], est[i, 1], math.cos(th), math.sin(th), vel[i, 0], vel[i, 1], 1.0 if leader[i] else 0.0,
                  slot[i] / slot_div, min(fix_age[i], max_fix_age),
                  math.sqrt(max(mean + half, 0.0)), math.sqrt(max(mean - half, 0.0)), math.cos(two_a),
                  math.sin(two_a), math.sqrt(max(cov[i, 2, 2], 0.0)),
                  cr * gx - sr * gy, sr * gx + cr * gy,
                  rel_xy[i, 0], rel_xy[i, 1], math.cos(rel_heading[i]) if seen else 0.0,
                  math.sin(rel_heading[i]) if seen else 0.0, 1.0 if seen else 0.0, kpois, time)
        for k in range(len(values)):
            if cols[k] >= 0:
                out[i, cols[k]] = values[k]


@njit(cache=True, nogil=True)
def formation_errors(poses, predecessor, offset, l_d, psi_d, dl, dpsi):
    """``dl[k], dpsi[k]`` of the ``k``-th follower (robot order): ``l - l_d`` and
    ``wrap(psi - psi_d)`` with ``l, psi`` the distance and bearing (in the predecessor's frame) of the
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
        psi = math.atan2(dy, dx) - poses[j, 2]
        dpsi[k] = math.pi - ((math.pi - (psi - psi_d)) % (2.0 * math.pi))
        k += 1
    return k
