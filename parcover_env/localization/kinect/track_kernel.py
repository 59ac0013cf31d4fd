"""Compiled (numba) identity tracking of the Kinect systems of ``K`` worlds in one call, the common
case of :meth:`KinectTracker.update <parcover_env.localization.kinect.tracker.KinectTracker.update>`
(public so that tests and other rooms may use it).

Per world: the estimates in the tracker's order (descending marker count, stable), each its own
fused pose when no two are within the fuse radius (``(w x) / w``, ``(w y) / w``,
``atan2(w sin theta, w cos theta)`` for the estimate's weight ``w``, the tracker's floats), matched
to the marker carrier within the gate when no estimate is within the gate of two carriers nor a
carrier of two (then the minimum-cost assignment holds exactly those pairs). Any other world (a
fused cluster, a crowded gate), or a distance within a relative ``1e-9`` of the fuse radius or the
gate (where two implementations of ``hypot`` could round to different sides), is flagged for the
tracker's own update, so the outcome is always the tracker's.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["match", "track_rows", "TrackRows", "track_scratch"]

_BAND = 1e-9
"""Relative margin around the fuse radius and the gate inside which a world is left to the tracker."""


@njit(cache=True)
def match(est, starts, ref, carriers, gate, fuse_radius, fused, robot, status):
    """Track the estimates of ``B`` worlds: ``est (E, 4)`` (x, y, theta, marker count) with world
    ``b``'s rows ``starts[b]:starts[b + 1]`` in its Kinects' order; ``ref (B, N, 2)`` the reference
    positions of the robots, ``carriers (B, N)`` the robots to match. Writes, in world ``b``'s rows
    in the tracker's order, the fused poses ``fused (E, 3)`` and the robot each is matched to
    (``robot (E,)``, -1: none), and ``status[b]`` = 1 where the world is left to the tracker (its
    rows then undefined), else 0."""
    n = ref.shape[1]
    for b in range(len(starts) - 1):
        s, e = starts[b], starts[b + 1]
        m = e - s
        status[b] = 0
        order = np.arange(s, e)
        for i in range(1, m):  # insertion sort: descending marker count, stable
            j = i
            while j > 0 and est[order[j - 1], 3] < est[order[j], 3]:
                order[j - 1], order[j] = order[j], order[j - 1]
                j -= 1
        for i in range(m):  # two estimates within the fuse radius (or near it) would fuse
            for j in range(i):
                d = math.hypot(est[order[j], 0] - est[order[i], 0], est[order[j], 1] - est[order[i], 1])
                if not d > fuse_radius * (1.0 + _BAND):
                    status[b] = 1
        if status[b]:
            continue
        for r in range(m):
            x, y, th, w = est[order[r], 0], est[order[r], 1], est[order[r], 2], est[order[r], 3]
            fused[s + r, 0] = (w * x) / w
            fused[s + r, 1] = (w * y) / w
            fused[s + r, 2] = math.atan2(w * math.sin(th), w * math.cos(th))
            robot[s + r] = -1
        per_robot = np.zeros(n, np.int64)
        for r in range(m):
            inside = 0
            for c in range(n):
                if not carriers[b, c]:
                    continue
                d = math.hypot(fused[s + r, 0] - ref[b, c, 0], fused[s + r, 1] - ref[b, c, 1])
                if abs(d - gate) <= gate * _BAND:
                    status[b] = 1  # too close to the gate to call here
                elif d <= gate:
                    inside += 1
                    per_robot[c] += 1
                    robot[s + r] = c
            if inside > 1:
                status[b] = 1
        for c in range(n):
            if per_robot[c] > 1:
                status[b] = 1


class TrackRows(NamedTuple):
    """Scratch outputs of :func:`track_rows` for up to ``E`` detections of ``B`` worlds (reused from
    step to step: a compiled call that returns new arrays pays for boxing each)."""

    est: np.ndarray
    """``(E, 4)``: each detection's ``(x, y, theta, marker count)``."""
    starts: np.ndarray
    """``(B + 1,)`` int64: world ``b``'s rows are ``starts[b]:starts[b + 1]``."""
    fused: np.ndarray
    """``(E, 3)``: :func:`match`'s fused poses."""
    robot: np.ndarray
    """``(E,)`` int64: :func:`match`'s robot of each row (-1: none)."""
    status: np.ndarray
    """``(B,)`` int64: :func:`match`'s status of each world."""


def track_scratch(detections: int, worlds: int) -> TrackRows:
    """Fresh :class:`TrackRows` for up to ``detections`` detections of ``worlds`` worlds."""
    return TrackRows(np.empty((detections, 4)), np.empty(worlds + 1, np.int64), np.empty((detections, 3)),
                     np.empty(detections, np.int64), np.empty(worlds, np.int64))


@njit(cache=True)
def track_rows(world, pose, n_markers, ref, carriers, gate, fuse_radius, est, starts, fused, robot, status):
    """:func:`match` of the detections of the ``B = carriers.shape[0]`` worlds: ``world (E,)``
    ascending (the world of each detection), ``pose (E, 3)``, each of ``n_markers`` markers;
    ``ref (B, N, >= 2)`` (only x, y read). Writes into the :class:`TrackRows` fields ``est, starts,
    fused, robot, status`` (at least ``E`` detections and ``B`` worlds) ``starts[:B + 1]`` (world
    ``b``'s rows ``starts[b]:starts[b + 1]``) and :func:`match`'s outputs in the first ``E`` rows and
    ``B`` worlds."""
    e = pose.shape[0]
    b_count = carriers.shape[0]
    est = est[:e]
    for r in range(e):
        est[r, 0] = pose[r, 0]
        est[r, 1] = pose[r, 1]
        est[r, 2] = pose[r, 2]
        est[r, 3] = n_markers
    starts = starts[:b_count + 1]
    j = 0
    for b in range(b_count + 1):  # the first row of world b or later (world ascending)
        while j < e and world[j] < b:
            j += 1
        starts[b] = j
    match(est, starts, ref, carriers, gate, fuse_radius, fused[:e], robot[:e], status[:b_count])
