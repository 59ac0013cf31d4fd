"""Compiled (numba) steps of the sonar localizer (:mod:`parcover_env.localization.sonar.localizer`).

Each kernel does the float operations of the numpy code it replaces, in the same order, so that the
localizer's poses are bit-identical to what it gave before it was compiled (issue 40;
``tests/references/sonar_localizer.py`` keeps that code, ``tests/localization/sonar`` compares):

* sums and means go through :mod:`parcover_env.geometry.numpy_order` (numpy's pairwise order);
* :func:`scan_error_row` is ``scan_error`` for one synthetic scan: with a trim, the kept errors are
  summed in ascending order (numpy's ``partition`` of a row of at most 256 values sorts it on CPUs with
  AVX-512; on other CPUs numpy's order, and so its last bits, differed from CPU to CPU);
* :func:`ellipse_distance` is ``Ellipse.distance`` (boundary sampled at 256 points, the cosines and
  sines computed by numpy once: :data:`EDGE_COS`, :data:`EDGE_SIN`);
* :func:`nelder_mead` is scipy's ``minimize(method="Nelder-Mead")`` with an initial simplex (scipy
  1.17: reflection 1, expansion 2, contraction 0.5, shrink 0.5), its simplex ordered as numpy's
  ``argsort`` orders four values (ties included: ``numpy_order.argsort4_table``, taken from numpy);
* :func:`free_status` tells whether a point lies in the free space (crossing number); a point within
  :data:`BOUNDARY_GUARD` of a wall is reported as undecided and the caller asks shapely instead.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.geometry.angle_kernels import wrap
from parcover_env.geometry.numpy_order import mean_of
from parcover_env.sensors.sonar_kernels import Discs, WallSet, pose_readings, pose_scratch

__all__ = ["EDGE_COS", "EDGE_SIN", "BOUNDARY_GUARD", "scan_error_row",
           "scan_errors", "ellipse_distance", "ellipse_beyond", "ellipse_distances", "free_status", "order_simplex",
           "nelder_mead", "pair_poses", "arc_count", "arc_poses", "feature_candidates", "first_unique", "ScanFit",
           "Simplex", "FeatureTable", "ScanRows", "CandidateRules"]

_EDGE_T = np.linspace(0, 2 * math.pi, 256, endpoint=False)
EDGE_COS = np.cos(_EDGE_T)
"""Cosines of the 256 boundary samples of ``Ellipse.distance`` (numpy's, as that method computed them)."""
EDGE_SIN = np.sin(_EDGE_T)
"""Their sines."""
BOUNDARY_GUARD = 1e-9
"""A point nearer than this to a wall (m) is not classified by :func:`free_status` (undecided)."""


class ScanFit(NamedTuple):
    """What the polish's cost compares: a measured scan and how its synthetic scans are made."""

    measured: np.ndarray
    """``(n,)`` measured ranges (m)."""
    angles: np.ndarray
    """``(n,)`` their robot-frame angles (rad)."""
    clip: float
    """Per-reading error cap (m)."""
    keep: int
    """Readings kept by the trim (the smallest errors)."""
    ell: np.ndarray
    """The ellipse record (:func:`ellipse_distance`)."""
    ecos: np.ndarray
    """Cosines of its boundary samples."""
    esin: np.ndarray
    """Sines of its boundary samples."""
    reach: float
    """A pose this far or farther from the ellipse costs ``clip`` (m)."""
    free: np.ndarray
    """``(S, 4)`` the free space's boundary segments (a pose outside costs ``clip``)."""
    walls: WallSet
    """The walls the synthetic scans see (:func:`parcover_env.sensors.sonar.beam_kernel_arguments`) ..."""
    offsets: np.ndarray
    """... the beams' sub-ray offsets ..."""
    share: np.ndarray
    """... their shared sub-rays ..."""
    discs: Discs
    """... no discs ..."""
    rules: np.ndarray
    """... and the sonar's rules record."""
    rmax: float
    """Readings are capped at this (m)."""


class Simplex(NamedTuple):
    """Nelder-Mead's settings (scipy's names)."""

    step: float
    """The initial simplex: ``x0`` and ``x0 + step`` along each axis."""
    maxiter: int
    xatol: float
    fatol: float
    table: np.ndarray
    """``numpy_order.argsort4_table``."""


class FeatureTable(NamedTuple):
    """The map's features as arrays (``localizer.MapFeature``)."""

    points: np.ndarray
    """``(F, 2)`` corners (m)."""
    normals: np.ndarray
    """``(F, 2, 2)`` unit normals of the two walls, into free space."""
    walls: np.ndarray
    """``(F, 2, 2)`` unit directions along the two walls, leaving the corner."""
    solvable: np.ndarray
    """``(F,)`` bool: the two normals are independent (LAPACK solves them)."""


class ScanRows(NamedTuple):
    """The walls and corners of one or more scans, rows ``(bearing, range, index)``."""

    walls: np.ndarray
    """``(W, 3)``; scan ``s`` has rows ``wstart[s]:wstart[s + 1]``."""
    wstart: np.ndarray
    corners: np.ndarray
    """``(K, 3)``; scan ``s`` has rows ``cstart[s]:cstart[s + 1]``."""
    cstart: np.ndarray


class CandidateRules(NamedTuple):
    """How Fig. 6's candidates are made and kept."""

    tol: float
    """Two wall-derived headings agree within this (rad)."""
    line_tol: float
    """Line tolerance of a corner-derived pose (m)."""
    ell: np.ndarray
    """The ellipse record (:func:`ellipse_distance`)."""
    ecos: np.ndarray
    esin: np.ndarray
    reach: float
    """Candidates nearer than this to the ellipse are kept (m)."""
    arc: bool
    """A pair without candidates gives arc poses."""
    arc_step: float
    """Their spacing along the arc (m)."""


@njit(cache=True, nogil=True)
def scan_error_row(measured, synth, clip, keep, buf):
    """``scan_error`` of one synthetic scan ``synth (n,)``: mean of the ``keep`` smallest clipped
    errors (``keep = n``: all, in reading order). ``buf (n,)`` is scratch."""
    n = measured.shape[0]
    for i in range(n):
        d = abs(synth[i] - measured[i])
        buf[i] = d if d < clip else clip
    if keep < n:
        buf[:] = np.sort(buf)
    return mean_of(buf, keep)


@njit(cache=True, nogil=True)
def scan_errors(measured, synth, clip, keep, out):
    """:func:`scan_error_row` of every row of ``synth (H, n)`` into ``out (H,)``."""
    buf = np.empty(measured.shape[0])
    for h in range(synth.shape[0]):
        out[h] = scan_error_row(measured, synth[h], clip, keep, buf)


@njit(cache=True, nogil=True)
def ellipse_distance(px, py, ell, ecos, esin):
    """Distance from ``(px, py)`` to the ellipse ``ell = (cx, cy, cos angle, sin angle, a, b)`` (the
    semi-axes at least 1e-9), 0 inside: its boundary sampled at ``ecos, esin`` (the square root of
    the smallest squared distance: the smallest root, as the root is correctly rounded and monotonic)."""
    p0 = px - ell[0]
    p1 = py - ell[1]
    c, s, a, b = ell[2], ell[3], ell[4], ell[5]
    l0 = c * p0 + s * p1
    l1 = -s * p0 + c * p1
    q0 = l0 / a
    q1 = l1 / b
    if q0 * q0 + q1 * q1 <= 1.0:
        return 0.0
    best = np.inf
    for k in range(ecos.shape[0]):
        d0 = l0 - a * ecos[k]
        d1 = l1 - b * esin[k]
        best = min(best, d0 * d0 + d1 * d1)
    return math.sqrt(best)


@njit(cache=True, nogil=True)
def ellipse_beyond(px, py, ell, reach):
    """Whether ``(px, py)`` is certainly ``reach`` or more from the ellipse's boundary samples: its
    distance from the centre less the larger semi-axis exceeds ``reach`` by 1e-9 (m), far more than
    the rounding of either side (a test that needs no samples)."""
    p0 = px - ell[0]
    p1 = py - ell[1]
    return math.sqrt(p0 * p0 + p1 * p1) - max(ell[4], ell[5]) > reach + 1e-9


@njit(cache=True, nogil=True)
def ellipse_distances(x, y, ell, ecos, esin, out):
    """:func:`ellipse_distance` of every point ``(x[i], y[i])`` into ``out``."""
    for i in range(x.shape[0]):
        out[i] = ellipse_distance(x[i], y[i], ell, ecos, esin)


@njit(cache=True, nogil=True)
def free_status(px, py, segs):
    """1 if ``(px, py)`` lies inside the region bounded by the closed rings of ``segs (S, 4)`` (even-odd
    rule), 0 if outside, -1 if within :data:`BOUNDARY_GUARD` of a segment (undecided)."""
    inside = False
    for k in range(segs.shape[0]):
        x1, y1, x2, y2 = segs[k, 0], segs[k, 1], segs[k, 2], segs[k, 3]
        ex = x2 - x1
        ey = y2 - y1
        ll = ex * ex + ey * ey
        t = 0.0
        if ll > 0.0:
            t = ((px - x1) * ex + (py - y1) * ey) / ll
            t = min(max(t, 0.0), 1.0)
        dx = x1 + t * ex - px
        dy = y1 + t * ey - py
        if dx * dx + dy * dy < BOUNDARY_GUARD * BOUNDARY_GUARD:
            return -1
        if (y1 > py) != (y2 > py) and px < x1 + (py - y1) * ex / ey:
            inside = not inside
    return 1 if inside else 0


@njit(cache=True, nogil=True)
def _cost(x, fit, axes, reading, synth, buf, ps):
    """The polish's cost of pose ``x``: ``clip`` outside the free space or ``reach`` or more from the
    ellipse, else the scan error of its synthetic scan; and whether the point was undecided."""
    st = free_status(x[0], x[1], fit.free)
    if st < 0:
        return fit.clip, True
    if st == 0 or ellipse_beyond(x[0], x[1], fit.ell, fit.reach) or \
            ellipse_distance(x[0], x[1], fit.ell, fit.ecos, fit.esin) >= fit.reach:
        return fit.clip, False
    angles = fit.angles
    for i in range(angles.shape[0]):
        axes[0, i] = x[2] + angles[i]
    pose_readings(x[0], x[1], axes[0], fit.share, fit.walls, fit.discs, fit.rules, reading[0], ps)
    rmax = fit.rmax
    for i in range(angles.shape[0]):
        v = reading[0, i]
        synth[i] = v if v < rmax else rmax
    return scan_error_row(fit.measured, synth, fit.clip, fit.keep, buf), False


@njit(cache=True, nogil=True)
def order_simplex(sim, fsim, table):
    """Reorder the simplex as numpy's ``argsort`` of ``fsim (4,)`` does (``table``: ``numpy_order.argsort4_table``)."""
    code = 0
    for k in range(4):
        rank = 0
        for j in range(4):
            if fsim[j] < fsim[k]:
                first = True
                for q in range(j):
                    if fsim[q] == fsim[j]:
                        first = False
                if first:
                    rank += 1
        code += rank * 4**k
    ind = table[code]
    s2 = sim.copy()
    f2 = fsim.copy()
    for k in range(4):
        sim[k] = s2[ind[k]]
        fsim[k] = f2[ind[k]]


@njit(cache=True, nogil=True)
def nelder_mead(x0, nm, fit):
    """scipy's Nelder-Mead (non-adaptive; settings ``nm``, a :class:`Simplex`) from the simplex ``x0`` and
    ``x0 + nm.step`` along each axis, minimizing :func:`_cost` of the :class:`ScanFit` ``fit``. Returns
    ``(x (3,), f, undecided)``: ``undecided`` when a point came within :data:`BOUNDARY_GUARD` of a wall
    (then ``x`` and ``f`` mean nothing)."""
    step, maxiter, xatol, fatol, table = nm.step, nm.maxiter, nm.xatol, nm.fatol, nm.table
    n = fit.angles.shape[0]
    axes = np.empty((1, n))
    reading = np.empty((1, n))
    synth = np.empty(n)
    buf = np.empty(n)
    ps = pose_scratch(fit.offsets, fit.share, fit.walls, fit.discs.cx.shape[1])
    sim = np.empty((4, 3))
    for k in range(4):
        for j in range(3):
            sim[k, j] = x0[j] + (step if k == j + 1 else 0.0)
    fsim = np.empty(4)
    for k in range(4):
        f, bad = _cost(sim[k], fit, axes, reading, synth, buf, ps)
        if bad:
            return sim[0].copy(), np.inf, True
        fsim[k] = f
    order_simplex(sim, fsim, table)
    order_simplex(sim, fsim, table)
    xbar = np.empty(3)
    xr = np.empty(3)
    xe = np.empty(3)
    iterations = 1
    while iterations < maxiter:
        dx = 0.0
        for k in range(1, 4):
            for j in range(3):
                dx = max(dx, abs(sim[k, j] - sim[0, j]))
        df = 0.0
        for k in range(1, 4):
            df = max(df, abs(fsim[0] - fsim[k]))
        if dx <= xatol and df <= fatol:
            break
        for j in range(3):
            xbar[j] = (((0.0 + sim[0, j]) + sim[1, j]) + sim[2, j]) / 3
            xr[j] = 2 * xbar[j] - sim[3, j]
        fxr, bad = _cost(xr, fit, axes, reading, synth, buf, ps)
        if bad:
            return sim[0].copy(), np.inf, True
        shrink = False
        if fxr < fsim[0]:
            for j in range(3):
                xe[j] = 3 * xbar[j] - 2 * sim[3, j]
            fxe, bad = _cost(xe, fit, axes, reading, synth, buf, ps)
            if bad:
                return sim[0].copy(), np.inf, True
            if fxe < fxr:
                sim[3] = xe
                fsim[3] = fxe
            else:
                sim[3] = xr
                fsim[3] = fxr
        elif fxr < fsim[2]:
            sim[3] = xr
            fsim[3] = fxr
        else:
            if fxr < fsim[3]:
                for j in range(3):
                    xe[j] = 1.5 * xbar[j] - 0.5 * sim[3, j]
                fxc, bad = _cost(xe, fit, axes, reading, synth, buf, ps)
                if bad:
                    return sim[0].copy(), np.inf, True
                if fxc <= fxr:
                    sim[3] = xe
                    fsim[3] = fxc
                else:
                    shrink = True
            else:
                for j in range(3):
                    xe[j] = 0.5 * xbar[j] + 0.5 * sim[3, j]
                fxcc, bad = _cost(xe, fit, axes, reading, synth, buf, ps)
                if bad:
                    return sim[0].copy(), np.inf, True
                if fxcc < fsim[3]:
                    sim[3] = xe
                    fsim[3] = fxcc
                else:
                    shrink = True
            if shrink:
                for k in range(1, 4):
                    for j in range(3):
                        sim[k, j] = sim[0, j] + 0.5 * (sim[k, j] - sim[0, j])
                    f, bad = _cost(sim[k], fit, axes, reading, synth, buf, ps)
                    if bad:
                        return sim[0].copy(), np.inf, True
                    fsim[k] = f
        iterations += 1
        order_simplex(sim, fsim, table)
    return sim[0].copy(), fsim.min(), False


@njit(cache=True, nogil=True)
def pair_poses(c, normals, solvable, walls, corners, tol, line_tol, out, m):
    """Poses ``(x, y, theta)`` from one map feature (corner ``c (2,)``, wall ``normals (2, 2)``) and one
    scan's ``walls (W, 3)`` and ``corners (K, 3)`` (rows bearing, range, index), written to ``out``
    from row ``m`` on (``localizer.pose_candidates``); returns the next free row."""
    nw = walls.shape[0]
    na0 = math.atan2(-normals[0, 1], -normals[0, 0])
    na1 = math.atan2(-normals[1, 1], -normals[1, 0])
    heads = np.empty((2, nw))
    for w in range(nw):
        heads[0, w] = wrap(na0 - walls[w, 0])
        heads[1, w] = wrap(na1 - walls[w, 0])
    rhs = np.empty(2)
    for w0 in range(nw):
        th0 = heads[0, w0]
        for w1 in range(nw):
            th1 = heads[1, w1]
            if walls[w0, 2] == walls[w1, 2] or abs(wrap(th0 - th1)) > tol or not solvable:
                continue
            th = math.atan2(math.sin(th0) + math.sin(th1), math.cos(th0) + math.cos(th1))
            rhs[0] = walls[w0, 1]
            rhs[1] = walls[w1, 1]
            p = np.linalg.solve(normals, rhs)
            out[m, 0] = c[0] + p[0]
            out[m, 1] = c[1] + p[1]
            out[m, 2] = th
            m += 1
    n = np.empty(2)
    d = np.empty(2)
    for i in range(2):
        n[0] = normals[i, 0]
        n[1] = normals[i, 1]
        for w in range(nw):
            th = heads[i, w]
            for k in range(corners.shape[0]):
                px = c[0] - corners[k, 1] * math.cos(th + corners[k, 0])
                py = c[1] - corners[k, 1] * math.sin(th + corners[k, 0])
                d[0] = px - c[0]
                d[1] = py - c[1]
                if abs(np.dot(n, d) - walls[w, 1]) <= 2 * line_tol + 0.02 * walls[w, 1]:
                    out[m, 0] = px
                    out[m, 1] = py
                    out[m, 2] = th
                    m += 1
    return m


@njit(cache=True, nogil=True)
def arc_count(fwalls, corners, step):
    """How many poses :func:`arc_poses` writes."""
    a1 = math.atan2(fwalls[0, 1], fwalls[0, 0])
    span = wrap(math.atan2(fwalls[1, 1], fwalls[1, 0]) - a1)
    total = 0
    for k in range(corners.shape[0]):
        total += max(2, int(abs(span) * corners[k, 1] / step)) - 1
    return total


@njit(cache=True, nogil=True)
def arc_poses(c, fwalls, corners, step, out, m):
    """Poses on the circle of each scan corner's range around the map corner ``c``, inside its wedge
    (``localizer.arc_candidates`` before the region test), written to ``out`` from row ``m`` on."""
    a1 = math.atan2(fwalls[0, 1], fwalls[0, 0])
    span = wrap(math.atan2(fwalls[1, 1], fwalls[1, 0]) - a1)
    for k in range(corners.shape[0]):
        n = max(2, int(abs(span) * corners[k, 1] / step))
        dpsi = span / n
        for i in range(1, n):
            y = i * dpsi if dpsi != 0 else (i / n) * span
            psi = a1 + (y + 0.0)
            out[m, 0] = c[0] + corners[k, 1] * math.cos(psi)
            out[m, 1] = c[1] + corners[k, 1] * math.sin(psi)
            out[m, 2] = wrap(psi + math.pi - corners[k, 0])
            m += 1
    return m


@njit(cache=True, nogil=True)
def feature_candidates(table, f1, scans, rules):
    """Fig. 6 candidates of every (map feature ``f1[i]`` of the :class:`FeatureTable`, scan ``s`` of the
    :class:`ScanRows`) pair in that order: the poses of :func:`pair_poses` within ``rules.reach`` of the
    ellipse; with ``rules.arc``, a pair without any gives its arc poses instead (to be tested against
    the grown ellipse by the caller). Returns ``(poses (M, 3), pair (M,), arcs (Q, 3), arc_pair (Q,))``,
    pair ``i * n_scans + s``."""
    points, normals, fwalls, solvable = table.points, table.normals, table.walls, table.solvable
    walls, wstart, corners, cstart = scans.walls, scans.wstart, scans.corners, scans.cstart
    tol, line_tol, ell, ecos, esin = rules.tol, rules.line_tol, rules.ell, rules.ecos, rules.esin
    reach, arc, arc_step = rules.reach, rules.arc, rules.arc_step
    n_scans = wstart.shape[0] - 1
    bound = 0
    for s in range(n_scans):
        nw = wstart[s + 1] - wstart[s]
        bound += nw * nw + 2 * nw * (cstart[s + 1] - cstart[s])
    poses = np.empty((bound * f1.shape[0], 3))
    pair = np.empty(bound * f1.shape[0], dtype=np.int64)
    buf = np.empty((bound, 3))
    arc_rows = 0
    keep_rows = 0
    empty = np.zeros(f1.shape[0] * n_scans, dtype=np.bool_)
    for i in range(f1.shape[0]):
        f = f1[i]
        for s in range(n_scans):
            sc_w = walls[wstart[s]:wstart[s + 1]]
            sc_c = corners[cstart[s]:cstart[s + 1]]
            m = pair_poses(points[f], normals[f], solvable[f], sc_w, sc_c, tol, line_tol, buf, 0)
            got = 0
            for q in range(m):
                if not ellipse_beyond(buf[q, 0], buf[q, 1], ell, reach) and \
                        ellipse_distance(buf[q, 0], buf[q, 1], ell, ecos, esin) < reach:
                    poses[keep_rows] = buf[q]
                    pair[keep_rows] = i * n_scans + s
                    keep_rows += 1
                    got += 1
            if got == 0 and arc:
                empty[i * n_scans + s] = True
                arc_rows += arc_count(fwalls[f], sc_c, arc_step)
    arcs = np.empty((arc_rows, 3))
    arc_pair = np.empty(arc_rows, dtype=np.int64)
    q = 0
    for i in range(f1.shape[0]):
        for s in range(n_scans):
            if empty[i * n_scans + s]:
                f = f1[i]
                q2 = arc_poses(points[f], fwalls[f], corners[cstart[s]:cstart[s + 1]], arc_step, arcs, q)
                arc_pair[q:q2] = i * n_scans + s
                q = q2
    return poses[:keep_rows], pair[:keep_rows], arcs, arc_pair


@njit(cache=True, nogil=True)
def first_unique(keys):
    """Indices of the first occurrence of each distinct row of ``keys (M, 3)``, ascending (rows equal as
    floats: ``-0.0 == 0.0``): numpy's ``unique(keys, axis=0, return_index=True)`` indices, sorted."""
    seen = dict()
    out = np.empty(keys.shape[0], dtype=np.int64)
    m = 0
    for i in range(keys.shape[0]):
        k = (keys[i, 0] + 0.0, keys[i, 1] + 0.0, keys[i, 2] + 0.0)
        if k not in seen:
            seen[k] = i
            out[m] = i
            m += 1
    return out[:m]
