"""Compiled (numba) reading of a 360-degree sonar scan: its characteristic points
(:func:`parcover_env.localization.sonar.features.characteristic_points`) and the Fig. 11 filter
(:func:`parcover_env.localization.sonar.filter.filter_scan`).

The same float operations in the same order as the numpy code they replace
(``tests/references/sonar_localizer.py``): means as numpy sums (:func:`~parcover_env.geometry.numpy_order.mean_of`
for a row, in row order for the column means of a point set), line fits by the same LAPACK SVD
(numba's ``np.linalg.svd``) and dot products by the same BLAS ``ddot`` (numba's ``np.dot`` of
contiguous vectors), sines and cosines of the reading angles computed once by numpy (``sin_a``,
``cos_a``), ``atan2`` from libm.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from parcover_env.geometry.angle_kernels import wrap
from parcover_env.geometry.numpy_order import mean_of

__all__ = ["LABEL_CODES", "characteristic_points", "filter_scan"]

LABEL_CODES = ".mcDMf"
"""The letter of each label code :func:`characteristic_points` returns (0 none, 1 m, 2 c, 3 D, 4 M, 5 f)."""


@njit(cache=True, nogil=True)
def _plateau(r, far, i, tol, buf, mark):
    """Readings (circular) within ``tol`` of reading ``i``, contiguous with it, in angular order:
    ``buf[lo:hi]`` (``buf (2n,)``, ``mark (n,)`` all False on entry and on return)."""
    n = r.shape[0]
    lo = n
    hi = n + 1
    buf[lo] = i
    mark[i] = True
    j = i
    for _ in range(n // 2):
        j = (j - 1) % n
        if far[j] or abs(r[j] - r[i]) > tol or mark[j]:
            break
        lo -= 1
        buf[lo] = j
        mark[j] = True
    j = i
    for _ in range(n // 2):
        j = (j + 1) % n
        if far[j] or abs(r[j] - r[i]) > tol or mark[j]:
            break
        buf[hi] = j
        hi += 1
        mark[j] = True
    for k in range(lo, hi):
        mark[buf[k]] = False
    return lo, hi


@njit(cache=True, nogil=True)
def _circular_mean(sin_a, cos_a, idx, lo, hi, tmp):
    m = hi - lo
    for k in range(m):
        tmp[k] = sin_a[idx[lo + k]]
    s = mean_of(tmp, m)
    for k in range(m):
        tmp[k] = cos_a[idx[lo + k]]
    c = mean_of(tmp, m)
    return math.atan2(s, c)


@njit(cache=True, nogil=True)
def _line_fit(x, y, m):
    """The line through the points ``(x[:m], y[:m])``: unit normal (pointing away from the origin side of
    the centroid), ``normal . centroid`` and the RMS residual (SVD of the centred points)."""
    cx = 0.0
    cy = 0.0
    for k in range(m):
        cx += x[k]
        cy += y[k]
    cx /= m
    cy /= m
    pts = np.empty((m, 2))
    for k in range(m):
        pts[k, 0] = x[k] - cx
        pts[k, 1] = y[k] - cy
    _, s, vt = np.linalg.svd(pts)
    normal = np.empty(2)
    normal[0] = vt[1, 0]
    normal[1] = vt[1, 1]
    centre = np.empty(2)
    centre[0] = cx
    centre[1] = cy
    if np.dot(normal, centre) < 0:
        normal[0] = -normal[0]
        normal[1] = -normal[1]
    return normal, centre, s[1] / math.sqrt(m)


@njit(cache=True, nogil=True)
def characteristic_points(r, sin_a, cos_a, range_max, far_margin, jump_threshold, prominence, window, plateau_tol,
                          line_tol, max_off_normal):
    """Characteristic points of the scan ``r (n,)`` (readings at angles whose sines and cosines are
    ``sin_a, cos_a``): ``(labels (n,) int8 codes of LABEL_CODES, corners (K, 3) rows (bearing, range,
    index), walls (L, 3) rows (bearing, distance, index))``. ``max_off_normal``: a wall's fitted normal
    replaces its plateau bearing when within this (rad)."""
    n = r.shape[0]
    far = np.empty(n, dtype=np.bool_)
    for i in range(n):
        far[i] = r[i] >= range_max - far_margin
    is_d = np.zeros(n, dtype=np.bool_)
    is_c = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        j = (i + 1) % n
        if not far[i] and not far[j] and abs(r[i] - r[j]) > jump_threshold:
            if r[i] > r[j]:
                is_d[i] = True
                is_c[j] = True
            else:
                is_d[j] = True
                is_c[i] = True
    w = min(window, (n - 1) // 2)
    labels = np.zeros(n, dtype=np.int8)
    loose = np.zeros(n, dtype=np.bool_)
    is_min = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        lmax = -np.inf
        rmax = -np.inf
        lmin = np.inf
        rmin = np.inf
        lmn = np.inf
        rmn = np.inf
        lfar = False
        rfar = False
        for k in range(1, w + 1):
            jl = (i - k) % n
            jr = (i + k) % n
            vl = -np.inf if far[jl] else r[jl]
            vr = -np.inf if far[jr] else r[jr]
            lmax = max(lmax, vl)
            rmax = max(rmax, vr)
            lmin = min(lmin, vl)
            rmin = min(rmin, vr)
            lmn = min(lmn, np.inf if far[jl] else r[jl])
            rmn = min(rmn, np.inf if far[jr] else r[jr])
            lfar = lfar or far[jl]
            rfar = rfar or far[jr]
        prom_l = lfar or (r[i] - (lmin if np.isfinite(lmin) else r[i]) >= prominence)
        prom_r = rfar or (r[i] - (rmin if np.isfinite(rmin) else r[i]) >= prominence)
        loose[i] = not far[i] and not is_c[i] and r[i] > lmax and r[i] >= rmax and prom_l and prom_r
        is_max = loose[i] and not far[(i - 1) % n] and not far[(i + 1) % n]
        is_min[i] = not far[i] and not is_d[i] and not is_c[i] and r[i] < lmn and r[i] <= rmn
        if far[i]:
            labels[i] = 5
        elif is_max:
            labels[i] = 4
        elif is_d[i]:
            labels[i] = 3
        elif is_c[i]:
            labels[i] = 2
        elif is_min[i]:
            labels[i] = 1
    buf = np.empty(2 * n, dtype=np.int64)
    mark = np.zeros(n, dtype=np.bool_)
    tmp = np.empty(n)
    corners = np.empty((int(loose.sum()), 3))
    k = 0
    for i in range(n):
        if loose[i]:
            lo, hi = _plateau(r, far, i, plateau_tol, buf, mark)
            corners[k, 0] = _circular_mean(sin_a, cos_a, buf, lo, hi, tmp)
            corners[k, 1] = r[i]
            corners[k, 2] = i
            k += 1
    walls = np.empty((int(is_min.sum()), 3))
    idx = np.empty(n + 2 * window, dtype=np.int64)
    px = np.empty(n + 2 * window)
    py = np.empty(n + 2 * window)
    k = 0
    for i in range(n):
        if not is_min[i]:
            continue
        lo, hi = _plateau(r, far, i, plateau_tol, buf, mark)
        bearing = _circular_mean(sin_a, cos_a, buf, lo, hi, tmp)
        # the plateau and ``window`` readings each side, first occurrences, no f
        m = 0
        for q in range(-window, hi - lo + window):
            if q < 0:
                j = (buf[lo] + q) % n
            elif q < hi - lo:
                j = buf[lo + q]
            else:
                j = (buf[hi - 1] + q - (hi - lo) + 1) % n
            seen = False
            for t in range(m):
                if idx[t] == j:
                    seen = True
            if not seen:
                idx[m] = j
                m += 1
        mm = 0
        for t in range(m):
            j = idx[t]
            if not far[j]:
                px[mm] = r[j] * cos_a[j]
                py[mm] = r[j] * sin_a[j]
                mm += 1
        if mm >= 3:
            normal, _, rms = _line_fit(px, py, mm)
            nb = math.atan2(normal[1], normal[0])
            if rms < line_tol and abs(wrap(nb - bearing)) < max_off_normal:
                bearing = nb
        walls[k, 0] = bearing
        walls[k, 1] = r[i]
        walls[k, 2] = i
        k += 1
    return labels, corners, walls


@njit(cache=True, nogil=True)
def filter_scan(ranges, sin_a, cos_a, range_max, repeats, half_window, line_tol):
    """Kim, Pearce & Amato's Fig. 11 filter of ``ranges (n,)`` (a filtered copy)."""
    r = ranges.copy()
    n = r.shape[0]
    done = np.zeros(n, dtype=np.bool_)
    m = 2 * half_window + 1
    px = np.empty(m)
    py = np.empty(m)
    u = np.empty(2)
    for _ in range(repeats):
        ms = -1
        for i in range(n):
            if not done[i] and r[i] < range_max and (ms < 0 or r[i] < r[ms]):
                ms = i
        if ms < 0:
            break
        done[ms] = True
        hit_far = False
        for k in range(m):
            j = (ms + k - half_window) % n
            if r[j] >= range_max:
                hit_far = True
            px[k] = r[j] * cos_a[j]
            py[k] = r[j] * sin_a[j]
        if hit_far:
            continue
        normal, centre, rms = _line_fit(px, py, m)
        dist = np.dot(normal, centre)
        if rms > line_tol:
            continue
        for step in (-1, 1):
            cur = ms
            for _ in range(n - 1):
                nxt = (cur + step) % n
                if nxt == ms or r[nxt] <= r[cur]:
                    break
                u[0] = cos_a[nxt]
                u[1] = sin_a[nxt]
                cos = np.dot(u, normal)
                if cos <= 0.05 or dist / cos > range_max or dist / cos > r[nxt] + line_tol:
                    break
                r[nxt] = dist / cos
                done[nxt] = True
                cur = nxt
    return r
