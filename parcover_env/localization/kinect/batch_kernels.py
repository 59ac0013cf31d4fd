"""Compiled (numba) steps of :func:`parcover_env.localization.kinect.batch_update.update_systems` around
the estimate kernel (public so that tests and other rooms may use them): the Kinect schedule of ``K``
worlds and the due Kinects' candidates in one call each, the same float operations as the numpy
formulas they replace (``ticks <= t + 1e-9``, ``t + period``)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from parcover_env.localization.kinect.estimate_kernel import candidates

__all__ = ["schedule", "due_candidates"]

DUE_SLACK = 1e-9
"""s: a Kinect whose next frame is at most this much after the clock is due."""


@njit(cache=True)
def schedule(ticks, times, periods, markers, true, due, active):
    """The Kinects due at the clocks ``times (K,)`` of ``K`` worlds: ``due[k, q]`` where
    ``ticks[k, q] <= times[k] + 1e-9``, and each due Kinect's next frame ``times[k] + periods[q]``
    written into ``ticks (K, S)``; ``active[k]``: some Kinect of world ``k`` is due and some robot
    carries markers (``markers (K, N)``). Returns True if every value of the true poses
    ``true (K, N, 3)`` is finite."""
    for k in range(ticks.shape[0]):
        now = times[k]
        some = False
        for q in range(ticks.shape[1]):
            due[k, q] = ticks[k, q] <= now + DUE_SLACK
            if due[k, q]:
                ticks[k, q] = now + periods[q]
                some = True
        carrier = False
        for i in range(markers.shape[1]):
            carrier = carrier or markers[k, i]
        active[k] = some and carrier
    finite = True
    for v in true.ravel():
        finite = finite and math.isfinite(v)
    return finite


@njit(cache=True)
def due_candidates(due, poses, carriers, kinects, pattern, depths, noise):
    """:func:`~parcover_env.localization.kinect.estimate_kernel.candidates` of the due Kinects
    ``due (K, S)`` (their rows in world-major order: row ``r`` is world ``world[r]``'s Kinect
    ``kinect[r]``, :data:`~parcover_env.localization.kinect.estimate_kernel.KINECT` row
    ``k S + q`` of ``kinects``). Returns ``(world, kinect, n, row_drop, out_row, out_index, out_geom)``,
    the candidate outputs cut to their ``n`` rows."""
    n_kinects = due.shape[1]
    count = 0
    for v in due.ravel():
        count += v
    index = np.empty((3, count), np.int64)
    r = 0
    for k in range(due.shape[0]):
        for q in range(n_kinects):
            if due[k, q]:
                index[0, r] = k * n_kinects + q
                index[1, r] = k
                index[2, r] = q
                r += 1
    cap = count * poses.shape[1]
    row_drop = np.empty(count)
    out_row = np.empty(cap, np.int64)
    out_index = np.empty(cap, np.int64)
    out_geom = np.empty((cap, 7))
    n = candidates(index, poses, carriers, kinects, pattern, depths, noise, row_drop, out_row, out_index, out_geom)
    return index[1], index[2], n, row_drop, out_row[:n], out_index[:n], out_geom[:n]
