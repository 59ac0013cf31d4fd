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

import numpy as np
from numba import njit

__all__ = ["match", "track_rows"]

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


@njit(cache=True)
def track_rows(world, pose, n_markers, b_count, ref, carriers, gate, fuse_radius):
    """:func:`match` of the detections of ``b_count`` worlds: ``world (E,)`` ascending (the world of
    each detection), ``pose (E, 3)``, each of ``n_markers`` markers; ``ref (B, N, >= 2)`` (only x, y
    read). Returns ``(starts (B + 1,), fused (E, 3), robot (E,), status (B,))``: world ``b``'s rows
    ``starts[b]:starts[b + 1]`` and :func:`match`'s outputs."""
    e = pose.shape[0]
    est = np.empty((e, 4))
    for r in range(e):
        est[r, 0] = pose[r, 0]
        est[r, 1] = pose[r, 1]
        est[r, 2] = pose[r, 2]
        est[r, 3] = n_markers
    starts = np.searchsorted(world, np.arange(b_count + 1))
    fused = np.empty((e, 3))
    robot = np.empty(e, np.int64)
    status = np.empty(b_count, np.int64)
    match(est, starts, ref, carriers, gate, fuse_radius, fused, robot, status)
    return starts, fused, robot, status
