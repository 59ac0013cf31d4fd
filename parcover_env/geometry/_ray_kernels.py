"""Compiled (numba) loops behind :mod:`parcover_env.geometry.rays`; import only through that module
(and :mod:`parcover_env.sensors.sonar` for :func:`sonar_echoes`).

Each (ray, segment) and (ray, disc) pair goes through the same IEEE float operations, in the same
order, as the formulas in the docstring of :mod:`~parcover_env.geometry.rays` (no fast-math, so no
fused multiply-add), so results do not depend on how the pairs are visited or culled. Compiled once
per machine: ``cache=True`` keeps the machine code on disk for the next process.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_EPS = 1e-12
"""Parallel rays (|direction x segment| below this) never hit; segment ends get this slack."""
_BOX_SLACK = 1e-9
"""Margin (m) of a ray's reach box: rounding never culls a segment the ray meets."""
_COS_FLOOR = 1e-9
"""Floor of a segment's length in ``|cos| = |d x e| / |e|`` (degenerate segments)."""


@njit(cache=True, inline="always")
def _segment_hit(x0, y0, ddx, ddy, segs, reach, cull, open_end):
    """Nearest segment hit of one ray: ``(t, index, d x e)``; ``(inf, -1, 0)`` if none.

    ``cull``: skip segments whose bounding box misses the box of ``[o, o + reach d]``.
    ``open_end``: stop at the first hit with ``0 < t < 1`` (blocking test) instead."""
    bx0 = bx1 = by0 = by1 = 0.0
    if cull:
        fx = x0 + ddx * reach
        fy = y0 + ddy * reach
        bx0 = min(x0, fx) - _BOX_SLACK
        bx1 = max(x0, fx) + _BOX_SLACK
        by0 = min(y0, fy) - _BOX_SLACK
        by1 = max(y0, fy) + _BOX_SLACK
    best = np.inf
    best_i = -1
    best_den = 0.0
    for s in range(segs.shape[0]):
        ax = segs[s, 0]
        ay = segs[s, 1]
        sx = segs[s, 2]
        sy = segs[s, 3]
        if cull and (min(ax, sx) > bx1 or max(ax, sx) < bx0 or min(ay, sy) > by1 or max(ay, sy) < by0):
            continue
        ex = sx - ax
        ey = sy - ay
        den = ddx * ey - ddy * ex
        if not abs(den) > _EPS:
            continue
        wx = ax - x0
        wy = ay - y0
        t = (wx * ey - wy * ex) / den
        u = (wx * ddy - wy * ddx) / den
        if not (t >= 0.0 and u >= -_EPS and u <= 1.0 + _EPS):
            continue
        if open_end:
            if t > 0.0 and t < 1.0:
                return t, s, den
        elif t < best:
            best = t
            best_i = s
            best_den = den
    if open_end:
        return np.inf, -1, 0.0
    return best, best_i, best_den


@njit(cache=True, inline="always")
def _disc_hit(x0, y0, ddx, ddy, cx, cy, row, r2, mine):
    """Nearest disc hit of one ray (inf if none) among discs ``cx[row], cy[row]`` but ``mine``."""
    best = np.inf
    for d in range(cx.shape[1]):
        if d == mine:
            continue
        ocx = x0 - cx[row, d]
        ocy = y0 - cy[row, d]
        c = (ocx * ocx + ocy * ocy) - r2[d]
        b = ocx * ddx + ocy * ddy
        disc = b * b - c
        if not disc >= 0.0:
            continue
        if c <= 0.0:
            t = 0.0
        else:
            t = -b - math.sqrt(disc)
            if not t >= 0.0:
                continue
        if t < best:
            best = t
    return best


@njit(cache=True, nogil=True)
def first_segment_hits(ox, oy, dx, dy, per, segs, seg_len, reach, box_cull, t_out, i_out, c_out):
    """Nearest segment hit of every ray ``r`` (origin ``r // per``) within ``reach``.

    ``segs (S, 4)``, ``seg_len (S,)`` = hypot of each segment's extent. Writes ``t_out`` (inf if
    none), ``i_out`` (-1 if none), ``c_out`` (``|cos|`` of incidence, 0 if none). Ties go to the
    lowest segment index. ``box_cull`` (only for a finite ``reach``) never changes a result."""
    cull = box_cull and math.isfinite(reach)
    for r in range(dx.shape[0]):
        o = r // per
        t, i, den = _segment_hit(ox[o], oy[o], dx[r], dy[r], segs, reach, cull, False)
        if i >= 0 and t <= reach:
            t_out[r] = t
            i_out[r] = i
            c_out[r] = abs(den) / max(seg_len[i], _COS_FLOOR)
        else:
            t_out[r] = np.inf
            i_out[r] = -1
            c_out[r] = 0.0


@njit(cache=True, nogil=True)
def first_disc_hits(ox, oy, dx, dy, per, cx, cy, r2, owner, reach, t_out):
    """Distance to the nearest disc hit of every ray ``r`` (origin ``o = r // per``) within ``reach``.

    Disc centres ``cx, cy (C, D)``: row ``o`` if ``C > 1`` (a disc set per origin), else row 0;
    ``r2 (D,)`` squared radii; ``owner[o]``: the disc to ignore (-1: none)."""
    per_origin = cx.shape[0] > 1
    for r in range(dx.shape[0]):
        o = r // per
        t = _disc_hit(ox[o], oy[o], dx[r], dy[r], cx, cy, o if per_origin else 0, r2, owner[o])
        t_out[r] = t if t <= reach else np.inf


@njit(cache=True, nogil=True)
def open_segments_blocked(ax, ay, bx, by, segs, out):
    """Whether the open segment ``a -> b`` (ray parameter ``0 < t < 1``) crosses one of ``segs``."""
    for r in range(ax.shape[0]):
        _, i, _ = _segment_hit(ax[r], ay[r], bx[r] - ax[r], by[r] - ay[r], segs, 1.0, True, True)
        out[r] = i >= 0


@njit(cache=True, nogil=True)
def sonar_echoes(ox, oy, dx, dy, per, segs, seg_len, cx, cy, r2, owner, rmax, specular, multipath,
                 cos_min, nudge, box_cull, out):
    """Echo distance of every sonar sub-ray ``r`` (origin ``r // per``), inf if none (the rules of
    :func:`parcover_env.sensors.sonar.simulate_beams`).

    First hit within ``rmax`` on the walls ``t1`` (incidence ``|cos| c1``) and on the discs ``td``.
    ``specular``: a wall echoes only if ``c1 >= cos_min``; with ``multipath`` an oblique wall
    mirrors the sub-ray, which starts again ``nudge`` off the wall and reads ``t1 + t2 + nudge``
    if its next surface (a normal-enough wall, or a disc; unlimited range for discs) lies within
    ``rmax - t1`` (``t2 + nudge`` compared). The walls of all second rays are cast with the same
    reach, the largest ``rmax - t1``. A disc nearer than the wall echoes (``td``)."""
    n_rays = dx.shape[0]
    cull = box_cull and math.isfinite(rmax)
    per_origin = cx.shape[0] > 1
    t1s = np.empty(n_rays)
    i1s = np.empty(n_rays, dtype=np.int64)
    reach2 = -np.inf
    for r in range(n_rays):
        o = r // per
        x0 = ox[o]
        y0 = oy[o]
        t1, i1, den = _segment_hit(x0, y0, dx[r], dy[r], segs, rmax, cull, False)
        td = _disc_hit(x0, y0, dx[r], dy[r], cx, cy, o if per_origin else 0, r2, owner[o])
        if not td <= rmax:
            td = np.inf
        if not (i1 >= 0 and t1 <= rmax):
            t1 = np.inf
            i1 = -1
        i1s[r] = -1
        if not specular:
            out[r] = min(t1, td)
            continue
        c1 = abs(den) / max(seg_len[i1], _COS_FLOOR) if i1 >= 0 else 0.0
        wall = np.inf
        if c1 >= cos_min:
            wall = t1
        elif multipath and i1 >= 0:
            i1s[r] = i1  # a second bounce, cast below
            reach2 = max(reach2, rmax - t1)
        t1s[r] = t1
        out[r] = td if td < t1 else wall
    if not specular or reach2 == -np.inf:
        return
    cull2 = box_cull and math.isfinite(reach2)
    for r in range(n_rays):
        i1 = i1s[r]
        if i1 < 0:
            continue
        t1 = t1s[r]
        if out[r] < t1:
            continue  # a disc in front of the wall
        o = r // per
        ddx = dx[r]
        ddy = dy[r]
        ex = segs[i1, 2] - segs[i1, 0]
        ey = segs[i1, 3] - segs[i1, 1]
        norm = math.sqrt(ex * ex + ey * ey)
        nx = -ey / norm
        ny = ex / norm
        f = 2.0 * (ddx * nx + ddy * ny)
        d2x = ddx - f * nx
        d2y = ddy - f * ny
        px = (ox[o] + ddx * t1) + d2x * nudge
        py = (oy[o] + ddy * t1) + d2y * nudge
        t2w, i2, den2 = _segment_hit(px, py, d2x, d2y, segs, reach2, cull2, False)
        if not (i2 >= 0 and t2w <= reach2):
            t2w = np.inf
            i2 = -1
        c2 = abs(den2) / max(seg_len[i2], _COS_FLOOR) if i2 >= 0 else 0.0
        wall2 = t2w if c2 >= cos_min else np.inf
        td2 = _disc_hit(px, py, d2x, d2y, cx, cy, o if per_origin else 0, r2, owner[o])
        t2 = (td2 if td2 < t2w else wall2) + nudge
        out[r] = t1 + t2 if t2 <= rmax - t1 else np.inf


@njit(cache=True, inline="always")
def _wrap(a):
    """``a`` wrapped to (-pi, pi], as :func:`parcover_env.geometry.angles.wrap_angle`."""
    return math.pi - ((math.pi - a) % (2.0 * math.pi))


@njit(cache=True, nogil=True)
def sonar_corner_echoes(ox, oy, axes, pts, u1, u2, segs, cx, cy, r2, owner, rmax, half, reading):
    """Lower ``reading (N, B)`` to the distance of every concave corner ``pts (C, 2)`` (wall
    directions ``u1, u2``) that origin ``n`` sees from inside the corner's wedge, within ``rmax``,
    with no wall (nor disc) in between, and inside beam ``b``'s cone (``|bearing - axis| <= half``);
    the concave-corner rule of :func:`parcover_env.sensors.sonar.simulate_beams`."""
    has_discs = cx.shape[1] > 0
    per_origin = cx.shape[0] > 1
    for n in range(ox.shape[0]):
        x0 = ox[n]
        y0 = oy[n]
        for c in range(pts.shape[0]):
            vx = pts[c, 0] - x0
            vy = pts[c, 1] - y0
            dist = math.sqrt(vx * vx + vy * vy)
            if not (dist <= rmax and dist > 1e-9):
                continue
            s = u1[c, 0] * u2[c, 1] - u1[c, 1] * u2[c, 0]
            wx = x0 - pts[c, 0]
            wy = y0 - pts[c, 1]
            if not ((u1[c, 0] * wy - u1[c, 1] * wx) * s > 0 and (wx * u2[c, 1] - wy * u2[c, 0]) * s > 0):
                continue  # not inside the corner's wedge
            dx = vx / dist
            dy = vy / dist
            t, _, _ = _segment_hit(x0, y0, dx, dy, segs, np.inf, False, False)
            if not t >= dist * (1.0 - 1e-7) - 1e-9:
                continue  # a wall in between
            if has_discs and not _disc_hit(x0, y0, dx, dy, cx, cy, n if per_origin else 0, r2, owner[n]) >= dist:
                continue  # a robot in between
            bearing = math.atan2(vy, vx)
            for b in range(axes.shape[1]):
                if abs(_wrap(bearing - axes[n, b])) <= half and dist < reading[n, b]:
                    reading[n, b] = dist


@njit(cache=True, nogil=True)
def sonar_crosstalk(px, py, pth, beams, segs, half, rmax, out):
    """Cross-talk readings ``out (K, N, B)`` (left inf where none) of robots ``(K, N)`` poses
    ``px, py, pth``: beam ``b`` of robot ``i`` reads ``d / 2`` from the nearest robot ``j`` of its world
    inside that beam's cone (``half``) with a beam of ``j`` pointing back at ``i``, ``0 < d / 2 <= rmax``
    and no wall between them; the rules of :func:`parcover_env.sensors.sonar.crosstalk`."""
    nb = beams.shape[0]
    for k in range(px.shape[0]):
        for i in range(px.shape[1]):
            for j in range(px.shape[1]):
                if i == j:
                    continue
                dx = px[k, j] - px[k, i]
                dy = py[k, j] - py[k, i]
                d = math.hypot(dx, dy)
                if not (d / 2 <= rmax and d > 0):
                    continue
                bearing = math.atan2(dy, dx)
                back = False
                for c in range(nb):
                    if abs(_wrap(bearing + math.pi - pth[k, j] - beams[c])) <= half:
                        back = True
                        break
                if not back:
                    continue
                _, hit, _ = _segment_hit(px[k, i], py[k, i], dx, dy, segs, 1.0, True, True)
                if hit >= 0:
                    continue  # a wall between them
                for b in range(nb):
                    if abs(_wrap(bearing - pth[k, i] - beams[b])) <= half and d / 2 < out[k, i, b]:
                        out[k, i, b] = d / 2
