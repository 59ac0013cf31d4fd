"""Compiled (numba) steps of :func:`parcover_env.localization.kinect.batch_update.update_systems` around
the estimate kernel (public so that tests and other rooms may use them): the Kinect schedule of ``K``
worlds and the due Kinects' candidates in one call each, the same float operations as the numpy
formulas they replace (``ticks <= t + 1e-9``, ``t + period``)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.localization.kinect.estimate_kernel import candidates

__all__ = ["schedule", "due_candidates", "CandidateRows", "candidate_rows"]

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


class CandidateRows(NamedTuple):
    """Scratch outputs of :func:`due_candidates` for up to ``R`` due Kinect rows and ``C`` candidates
    (reused from step to step: a compiled call that returns new arrays pays for boxing each)."""

    index: np.ndarray
    """``(3 R,)`` int64: for the ``R'`` due rows, the ``(3, R')`` block of their
    :data:`~parcover_env.localization.kinect.estimate_kernel.KINECT` rows, worlds and Kinects."""
    drop: np.ndarray
    """``(R,)``: the row's frame drop rate."""
    row: np.ndarray
    """``(C,)`` int64: the row of each candidate."""
    robot: np.ndarray
    """``(C,)`` int64: the carrier of each candidate."""
    geom: np.ndarray
    """``(C, 7)``: each candidate's detection probability, merged flag, sigmas and pose."""


def candidate_rows(rows: int, cands: int) -> CandidateRows:
    """Fresh :class:`CandidateRows` for ``rows`` due Kinects and ``cands`` candidates."""
    return CandidateRows(np.empty(3 * rows, np.int64), np.empty(rows), np.empty(cands, np.int64),
                         np.empty(cands, np.int64), np.empty((cands, 7)))


@njit(cache=True)
def due_candidates(due, poses, carriers, kinects, pattern, depths, noise, index, drop, row, robot, geom):
    """:func:`~parcover_env.localization.kinect.estimate_kernel.candidates` of the due Kinects
    ``due (K, S)`` (their rows in world-major order), written into the :class:`CandidateRows` fields
    ``index, drop, row, robot, geom`` (at least ``K S`` rows and ``K S N`` candidates; ``index`` flat,
    its first ``3 R`` entries the ``(3, R)`` block of the ``R`` due rows: row ``r`` is world
    ``index[R + r]``'s Kinect ``index[2 R + r]``, :data:`~parcover_env.localization.kinect.estimate_kernel.KINECT`
    row ``k S + q`` of ``kinects``). Returns ``(R, n)``: the due rows and the candidates written."""
    n_kinects = due.shape[1]
    count = 0
    for v in due.ravel():
        count += v
    rows = index[:3 * count].reshape((3, count))
    r = 0
    for k in range(due.shape[0]):
        for q in range(n_kinects):
            if due[k, q]:
                rows[0, r] = k * n_kinects + q
                rows[1, r] = k
                rows[2, r] = q
                r += 1
    n = candidates(rows, poses, carriers, kinects, pattern, depths, noise, drop, row, robot, geom)
    return count, n
