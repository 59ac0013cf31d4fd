"""Compiled scan errors of many candidate poses with an exact early exit (the grid fallback's, issue 40).

:func:`bounded_scan_errors` gives each pose the scan error that
:func:`~parcover_env.localization.sonar.localizer.scan_error` gives its synthetic scan
(:func:`~parcover_env.sensors.sonar.simulate_beams`), bit for bit, or ``inf`` for a pose whose error
provably exceeds the smallest one before it: a pose that can neither be the smallest nor tie with it,
so the localizer's choice (the first smallest error) is the same. The bound comes before a pose's second
legs (the sonar's costliest step): a beam's echo lies between the nearest direct, corner or first-leg
distance of its cone and its reading without second legs (a two-leg echo reads more than its first leg),
so each reading's clipped error is at least its measured range's distance to that interval, and the
error is at least the mean of the ``keep`` smallest of these.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.geometry.ray_kernels import near_segments
from parcover_env.localization.sonar.localizer_kernels import scan_error_row
from parcover_env.sensors.sonar_kernels import (
    FAN_SPANS_MIN,
    DiscRow,
    WallBoxes,
    corner_scratch,
    corner_view,
    echo_scratch,
    origin_corners,
    origin_first_legs,
    origin_second_legs,
)

__all__ = ["BOUND_SLACK", "ScanTarget", "bounded_scan_errors", "error_floor"]

class ScanTarget(NamedTuple):
    """What :func:`bounded_scan_errors` scores against: the measured scan ``(B,)`` (m), the per-reading error
    clip (m), how many of the smallest errors are kept, and the smallest error so far (m; inf: none)."""

    measured: np.ndarray
    clip: float
    keep: int
    best: float


BOUND_SLACK = 1e-9
"""Relative margin (and 1e-12 m absolute) by which a pose's error bound must exceed the smallest error so far
before the pose is skipped: far above the rounding of a sum of 72 clipped errors (~1e-14 relative)."""


@njit(cache=True, inline="always")
def error_floor(measured, low, high, rmax, clip, keep, buf):
    """The least sum of the ``keep`` smallest clipped errors (m) that readings in ``[low[b], high[b]]`` (each
    then ``min(., rmax)``) can give against ``measured (B,)``: each reading's distance to its interval,
    clipped at ``clip``, the ``keep`` smallest summed in ascending order; ``buf (B,)`` is scratch."""
    for b in range(measured.shape[0]):
        lo = low[b] if low[b] < rmax else rmax
        hi = high[b] if high[b] < rmax else rmax
        m = measured[b]
        d = lo - m if m < lo else (m - hi if m > hi else 0.0)
        buf[b] = d if d < clip else clip
    buf[:] = np.sort(buf)
    total = 0.0
    for b in range(keep):
        total += buf[b]
    return total


@njit(cache=True, nogil=True)
def bounded_scan_errors(ox, oy, axes, offsets, share, walls, discs, rules, target, out):
    """``out[h]``: the scan error (:func:`~parcover_env.localization.sonar.localizer_kernels.scan_error_row`:
    the :class:`ScanTarget` ``target``'s ``keep`` smallest clipped errors) of its measured scan ``(B,)`` against
    the noise-free readings of the beams ``axes[h] (B,)`` from ``(ox[h], oy[h])``
    (:func:`~parcover_env.sensors.sonar_kernels.beam_readings`' with ``walls``, ``discs``, ``offsets``, ``share``
    and ``rules``, then ``min(., range_max)``), or inf when :func:`error_floor` of its echo intervals (known
    before its second legs) exceeds the smallest error so far (``target.best``, then ``out`` of the poses
    tried before ``h``) by :data:`BOUND_SLACK`."""
    measured, clip, keep, best = target.measured, target.clip, target.keep, target.best
    rule = rules[0]
    rmax = rule.range_max
    segs = walls.segments
    n, nb = axes.shape
    idx = np.empty((n, segs.shape[0]), dtype=np.int64)
    cnt = np.empty(n, dtype=np.int64)
    near_segments(ox, oy, segs, rule.range_max + rule.near_slack, idx, cnt)
    cx, cy, r2, owner = discs.cx, discs.cy, discs.r2, discs.owner
    per_origin = cx.shape[0] > 1
    sc = echo_scratch(offsets, share, segs, cx.shape[1])
    reading = np.empty(nb)
    mirror = np.empty(nb)
    low = np.empty(nb)
    synth = np.empty(nb)
    buf = np.empty(nb)
    corners = rule.specular and walls.points.shape[0] > 0
    view = corner_scratch(walls)
    limit = best
    for h in range(n):
        x0 = ox[h]
        y0 = oy[h]
        row = h if per_origin else 0
        near = idx[h, :cnt[h]]
        seen = DiscRow(cx, cy, row, r2, owner[h])
        m = origin_first_legs(x0, y0, axes[h], share, walls, near, seen, rules, sc, reading, mirror)
        if corners:  # the corners lower the direct readings now (the same minimum as after the second legs)
            # the corners seen and their lines of sight are those of the pose before at the same spot (the grid's
            # headings follow each other)
            if h == 0 or per_origin or x0 != ox[h - 1] or y0 != oy[h - 1] or owner[h] != owner[h - 1]:
                corner_view(x0, y0, walls, near, rules, view)
            origin_corners(x0, y0, axes[h], walls, near, seen, rules, reading, WallBoxes(sc.boxes, sc.meets),
                           sc.fdx.shape[0] >= FAN_SPANS_MIN, view)
        if limit < np.inf:
            for b in range(nb):
                low[b] = min(reading[b], mirror[b])
            if error_floor(measured, low, reading, rmax, clip, keep, buf) > limit * keep * (1.0 + BOUND_SLACK) + 1e-12:
                out[h] = np.inf
                continue
        origin_second_legs(x0, y0, share, walls, near, m, owner, rules, sc, reading, mirror)
        for b in range(nb):
            v = reading[b]
            synth[b] = v if v < rmax else rmax
        e = scan_error_row(measured, synth, clip, keep, buf)
        out[h] = e
        limit = min(limit, e)
