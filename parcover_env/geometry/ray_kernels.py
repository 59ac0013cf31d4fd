"""Compiled (numba) loops behind :mod:`parcover_env.geometry.rays`, and the per-ray helpers every
compiled caster shares (:func:`segment_hit`, :func:`disc_hit`, :func:`disc_hit_from`, :func:`in_cone`;
the sonar's loops, :mod:`parcover_env.sensors.sonar_kernels`, build on them). Public so that kernels
of other rooms and tests use these, one implementation each; Python code casts through
:mod:`~parcover_env.geometry.rays`.

Each (ray, segment) and (ray, disc) pair goes through the same IEEE float operations, in the same
order, as the formulas in the docstring of :mod:`~parcover_env.geometry.rays` (no fast-math, so no
fused multiply-add), so results do not depend on how the pairs are visited or culled. Compiled once
per machine: ``cache=True`` keeps the machine code on disk for the next process.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from parcover_env.geometry.angle_kernels import wrap

_EPS = 1e-12
"""Parallel rays (|direction x segment| below this) never hit; segment ends get this slack."""
_BOX_SLACK = 1e-9
"""Margin (m) of a ray's reach box: rounding never culls a segment the ray meets."""
BOX_SLACK = _BOX_SLACK
"""The reach box's margin, for the fast ring, which builds the boxes :func:`segment_fan` culls with."""
COS_FLOOR = 1e-9
"""Floor of a segment's length in ``|cos| = |d x e| / |e|`` (degenerate segments)."""


@njit(cache=True, inline="always")
def segment_hit(x0, y0, ddx, ddy, segs, idx, reach, cull, open_end):
    """Nearest hit of one ray on the segments ``idx`` (ascending indices into ``segs``):
    ``(t, index, d x e)``; ``(inf, -1, 0)`` if none.

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
    for j in range(idx.shape[0]):
        s = idx[j]
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


_SIGHT_SLACK = 1e-7
"""Margin (m) of the box :func:`wall_before` culls with (a hundred times ``segment_hit``'s)."""


@njit(cache=True, inline="always")
def wall_before(x0, y0, ddx, ddy, segs, idx, limit, far):
    """Whether one of the segments ``idx`` is hit nearer than ``limit`` by the ray from ``(x0, y0)``
    along the unit ``(ddx, ddy)``: ``segment_hit(...)[0] < limit`` (no culling there), the same test of
    each segment, stopping at the first such hit and skipping segments whose bounding box misses the
    box of ``[o, o + far d]`` (``far >= limit``) by :data:`_SIGHT_SLACK` (they hold no hit before ``far``)."""
    fx = x0 + ddx * far
    fy = y0 + ddy * far
    bx0 = min(x0, fx) - _SIGHT_SLACK
    bx1 = max(x0, fx) + _SIGHT_SLACK
    by0 = min(y0, fy) - _SIGHT_SLACK
    by1 = max(y0, fy) + _SIGHT_SLACK
    for j in range(idx.shape[0]):
        s = idx[j]
        ax = segs[s, 0]
        ay = segs[s, 1]
        sx = segs[s, 2]
        sy = segs[s, 3]
        if min(ax, sx) > bx1 or max(ax, sx) < bx0 or min(ay, sy) > by1 or max(ay, sy) < by0:
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
        if t >= 0.0 and u >= -_EPS and u <= 1.0 + _EPS and t < limit:
            return True
    return False


@njit(cache=True, inline="always")
def _disc_t(b, c):
    """Distance to a disc along a unit ray from ``b = oc . d`` and ``c = |oc|^2 - r^2``
    (``oc`` = origin - centre): 0 if the ray starts inside, inf if it misses."""
    if c > 0.0 and b >= 0.0:
        return np.inf  # starts outside, points away: -b - sqrt(b^2 - c) < 0
    disc = b * b - c
    if not disc >= 0.0:
        return np.inf
    if c <= 0.0:
        return 0.0
    t = -b - math.sqrt(disc)
    return t if t >= 0.0 else np.inf


@njit(cache=True, inline="always")
def disc_hit(x0, y0, ddx, ddy, cx, cy, row, r2, mine):
    """Nearest disc hit of one ray (inf if none) among discs ``cx[row], cy[row]`` but ``mine``."""
    best = np.inf
    for d in range(cx.shape[1]):
        if d == mine:
            continue
        ocx = x0 - cx[row, d]
        ocy = y0 - cy[row, d]
        c = (ocx * ocx + ocy * ocy) - r2[d]
        b = ocx * ddx + ocy * ddy
        best = min(best, _disc_t(b, c))
    return best


@njit(cache=True, inline="always")
def disc_hit_from(ddx, ddy, ocx, ocy, cc):
    """:func:`disc_hit` with the origin's disc terms ``oc = o - c`` and ``|oc|^2 - r^2`` computed
    once for many rays (``cc`` = inf for a disc to skip); the same numbers."""
    best = np.inf
    for d in range(ocx.shape[0]):
        c = cc[d]
        b = ocx[d] * ddx + ocy[d] * ddy
        best = min(best, _disc_t(b, c))
    return best


@njit(cache=True, nogil=True)
def first_segment_hits(ox, oy, dx, dy, per, segs, seg_len, reach, box_cull, t_out, i_out, c_out):
    """Nearest segment hit of every ray ``r`` (origin ``r // per``) within ``reach``.

    ``segs (S, 4)``, ``seg_len (S,)`` = hypot of each segment's extent. Writes ``t_out`` (inf if
    none), ``i_out`` (-1 if none), ``c_out`` (``|cos|`` of incidence, 0 if none). Ties go to the
    lowest segment index. ``box_cull`` (only for a finite ``reach``) never changes a result."""
    cull = box_cull and math.isfinite(reach)
    every = np.arange(segs.shape[0])
    for r in range(dx.shape[0]):
        o = r // per
        t, i, den = segment_hit(ox[o], oy[o], dx[r], dy[r], segs, every, reach, cull, False)
        if i >= 0 and t <= reach:
            t_out[r] = t
            i_out[r] = i
            c_out[r] = abs(den) / max(seg_len[i], COS_FLOOR)
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
        t = disc_hit(ox[o], oy[o], dx[r], dy[r], cx, cy, o if per_origin else 0, r2, owner[o])
        t_out[r] = t if t <= reach else np.inf


@njit(cache=True, nogil=True)
def open_segments_blocked(ax, ay, bx, by, segs, out):
    """Whether the open segment ``a -> b`` (ray parameter ``0 < t < 1``) crosses one of ``segs``."""
    every = np.arange(segs.shape[0])
    for r in range(ax.shape[0]):
        _, i, _ = segment_hit(ax[r], ay[r], bx[r] - ax[r], by[r] - ay[r], segs, every, 1.0, True, True)
        out[r] = i >= 0


@njit(cache=True, nogil=True)
def sight_lines_blocked(px, py, target, segs, out):
    """Whether the open segment from point ``i`` to point ``target[i]`` crosses one of ``segs``
    (:func:`open_segments_blocked` of that pair); False where ``target[i] < 0``."""
    every = np.arange(segs.shape[0])
    for i in range(px.shape[0]):
        j = target[i]
        out[i] = False
        if j >= 0:
            _, hit, _ = segment_hit(px[i], py[i], px[j] - px[i], py[j] - py[i], segs, every, 1.0, True, True)
            out[i] = hit >= 0


@njit(cache=True, nogil=True)
def near_segments(ox, oy, segs, reach, idx, cnt):
    """Per origin ``o``, the indices (ascending) of the segments within ``reach`` of it by
    point-to-segment distance: ``idx[o, :cnt[o]]``. A path of rays leaving ``o`` meets no other
    segment within that length, so restricting its casts to the list changes no result."""
    for o in range(ox.shape[0]):
        c = 0
        for s in range(segs.shape[0]):
            if segment_within(ox[o], oy[o], segs, s, reach):
                idx[o, c] = s
                c += 1
        cnt[o] = c


@njit(cache=True, inline="always")
def segment_within(x, y, segs, s, reach):
    """Whether segment ``s`` of ``segs`` lies within ``reach`` of the point ``(x, y)`` (point-to-segment
    distance; the test of :func:`near_segments`)."""
    ax = segs[s, 0]
    ay = segs[s, 1]
    ex = segs[s, 2] - ax
    ey = segs[s, 3] - ay
    wx = x - ax
    wy = y - ay
    ll = ex * ex + ey * ey
    u = min(max((wx * ex + wy * ey) / ll, 0.0), 1.0) if ll > 0.0 else 0.0
    px = wx - u * ex
    py = wy - u * ey
    return px * px + py * py <= reach * reach


@njit(cache=True, inline="always")
def in_cone(a, half):
    """``|wrap(a)| <= half``, exactly; a cheap rounding-based wrap first rejects angles clearly
    outside (it agrees with :func:`~parcover_env.geometry.angle_kernels.wrap` to ~1e-15 rad, far below
    the 1e-9 rad margin)."""
    if abs(a - 2.0 * math.pi * round(a / (2.0 * math.pi))) > half + 1e-9:
        return False
    return abs(wrap(a)) <= half


@njit(cache=True, nogil=True, error_model="numpy")
def segment_fan(x0, y0, dx, dy, segs, near, boxes, t, index, dens):
    """:func:`segment_hit` (not ``open_end``) of every ray ``b`` of a fan from ``(x0, y0)``, unit
    directions ``(dx[b], dy[b])``, on the segments ``near`` (ascending indices into ``segs``): writes its
    ``t[b]``, ``index[b]`` and ``dens[b]`` (``inf, -1, 0`` if none). The same float operations, one
    segment at a time for all rays (a loop the compiler vectorizes; divisions by a near-zero ``den`` are
    computed and discarded); a tie keeps the earlier segment, as there. ``boxes (4, B)``: each ray's
    reach box (x low, x high, y low, y high) outside which a segment is skipped (``segment_hit``'s
    culling), or ``(0, B)``: no culling."""
    nb = dx.shape[0]
    cull = boxes.shape[0] > 0
    for b in range(nb):
        t[b] = np.inf
        index[b] = -1
        dens[b] = 0.0
    for j in range(near.shape[0]):
        s = near[j]
        ax = segs[s, 0]
        ay = segs[s, 1]
        sx = segs[s, 2]
        sy = segs[s, 3]
        lox = min(ax, sx)
        hix = max(ax, sx)
        loy = min(ay, sy)
        hiy = max(ay, sy)
        ex = sx - ax
        ey = sy - ay
        wx = ax - x0
        wy = ay - y0
        num = wx * ey - wy * ex
        for b in range(nb):
            den = dx[b] * ey - dy[b] * ex
            tt = num / den
            u = (wx * dy[b] - wy * dx[b]) / den
            hit = abs(den) > _EPS and tt >= 0.0 and u >= -_EPS and u <= 1.0 + _EPS and tt < t[b]
            if cull:
                hit = hit and not (lox > boxes[1, b] or hix < boxes[0, b] or loy > boxes[3, b] or hiy < boxes[2, b])
            t[b] = tt if hit else t[b]
            index[b] = s if hit else index[b]
            dens[b] = den if hit else dens[b]


@njit(cache=True, nogil=True, error_model="numpy")
def disc_fan(dx, dy, ocx, ocy, cc, best):
    """Lower ``best[b]`` to the nearest hit of ray ``b`` (unit directions ``dx, dy``) on the discs
    whose terms ``oc = origin - centre`` and ``|oc|^2 - r^2`` are ``ocx, ocy, cc``: the distances of
    :func:`disc_hit_from` (0 from inside a disc, inf on a miss), one disc at a time for all rays,
    branch-free."""
    nb = dx.shape[0]
    for d in range(ocx.shape[0]):
        c = cc[d]
        x = ocx[d]
        y = ocy[d]
        for b in range(nb):
            bb = x * dx[b] + y * dy[b]
            disc = bb * bb - c
            t = -bb - math.sqrt(max(disc, 0.0))
            inside = c <= 0.0  # the ray starts inside: 0
            hit = disc >= 0.0 and (inside or (bb < 0.0 and t >= 0.0))
            best[b] = min(best[b], (0.0 if inside else t) if hit else np.inf)


SPAN_MARGIN = 2e-6
"""Margin of :func:`segment_fan_spans`' angular culling in pseudo-angle units (:func:`pseudo_angle`;
one unit is at least 1/2 rad and at most 1 rad of turn, so this is at least 2e-6 rad: far above the
angles that the segment ends' ``u`` slack and rounding move a hit by, with the origin at least
:data:`SPAN_GUARD` off the segment's line)."""
SPAN_GUARD = 1e-3
"""An origin closer than this (m) to a segment's line tests the segment against every ray."""


@njit(cache=True, inline="always")
def pseudo_angle(x, y):
    """A monotone stand-in for the angle of the vector ``(x, y)`` (not zero): ``[0, 4)`` over a turn
    counter-clockwise from +x (``y / (x + y)`` in the first quadrant, likewise in the others); one
    division. Its slope is between 1/2 and 1 per radian."""
    if y >= 0.0:
        return y / (x + y) if x >= 0.0 else 1.0 + (-x) / (y - x)
    return 2.0 + (-y) / (-x - y) if x < 0.0 else 3.0 + x / (x - y)


@njit(cache=True, inline="always")
def _first_above(keys, value, n):
    """The first position ``q`` of the ascending ``keys[:n]`` with ``keys[q] >= value`` (``n`` if none)."""
    lo = 0
    hi = n
    while lo < hi:
        mid = (lo + hi) // 2
        if keys[mid] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, nogil=True, error_model="numpy")
def segment_fan_spans(x0, y0, dx, dy, segs, near, order, keys, t, index, dens):
    """:func:`segment_fan` without culling (the same ``t``, ``index``, ``dens`` bit for bit), each segment
    tested only against the rays within its angular span from ``(x0, y0)``: a ray that hits a segment
    points between the directions to its two ends (widened by :data:`SPAN_MARGIN`), so the others
    cannot (an origin within :data:`SPAN_GUARD` of a segment's line tests it against every ray).
    ``order`` (R,) int64 is scratch that may hold the previous call's ray order (a fan turned by a
    little, e.g. the next pose of a scan, sorts in one pass); ``keys`` (R,) is scratch. A ray's
    segments are still met in ascending order, so a tie keeps the earlier segment, as there."""
    nr = dx.shape[0]
    for b in range(nr):
        t[b] = np.inf
        index[b] = -1
        dens[b] = 0.0
    if nr == 0:
        return
    valid = True  # ``order`` a permutation of the rays? (else start from the identity)
    for q in range(nr):
        if not (0 <= order[q] < nr):
            valid = False
    if valid:
        seen = np.zeros(nr, dtype=np.bool_)
        for q in range(nr):
            if seen[order[q]]:
                valid = False
            seen[order[q]] = True
    if not valid:
        for q in range(nr):
            order[q] = q
    for q in range(nr):
        keys[q] = pseudo_angle(dx[order[q]], dy[order[q]])
    # rotate to the smallest key, then insertion sort (one pass when the order only turned)
    low = 0
    for q in range(1, nr):
        if keys[q] < keys[low]:
            low = q
    if low > 0:
        o2 = order.copy()
        k2 = keys.copy()
        for q in range(nr):
            order[q] = o2[(q + low) % nr]
            keys[q] = k2[(q + low) % nr]
    for q in range(1, nr):
        kq = keys[q]
        oq = order[q]
        p = q - 1
        while p >= 0 and keys[p] > kq:
            keys[p + 1] = keys[p]
            order[p + 1] = order[p]
            p -= 1
        keys[p + 1] = kq
        order[p + 1] = oq
    for j in range(near.shape[0]):
        s = near[j]
        ax = segs[s, 0]
        ay = segs[s, 1]
        sx = segs[s, 2]
        sy = segs[s, 3]
        ex = sx - ax
        ey = sy - ay
        wx = ax - x0
        wy = ay - y0
        num = wx * ey - wy * ex
        ll = math.sqrt(ex * ex + ey * ey)
        first = 0
        last = nr  # every ray (a guard case), else the rays from ``first`` to ``last`` (exclusive, wrapped)
        if abs(num) > SPAN_GUARD * ll:  # the origin is off the segment's line: its span is below half a turn
            pa = pseudo_angle(wx, wy)
            pb = pseudo_angle(sx - x0, sy - y0)
            lo, hi = (pa, pb) if num > 0.0 else (pb, pa)  # counter-clockwise from lo to hi
            if hi < lo:
                hi += 4.0
            lo -= SPAN_MARGIN
            hi += SPAN_MARGIN
            if lo < 0.0:
                lo += 4.0
                hi += 4.0
            first = _first_above(keys, lo, nr)
            last = _first_above(keys, hi, nr) if hi < 4.0 else nr + _first_above(keys, hi - 4.0, nr)
        for q in range(first, min(last, first + nr)):
            b = order[q % nr]
            den = dx[b] * ey - dy[b] * ex
            tt = num / den
            u = (wx * dy[b] - wy * dx[b]) / den
            if abs(den) > _EPS and tt >= 0.0 and u >= -_EPS and u <= 1.0 + _EPS and tt < t[b]:
                t[b] = tt
                index[b] = s
                dens[b] = den


@njit(cache=True, inline="always")
def near_boxes(segs, near, boxes):
    """Fill ``boxes[:, :len(near)]`` (``(4, >= len(near))``) with the bounding boxes (x low, x high, y low,
    y high) of the segments ``near``, contiguous for :func:`segment_hit_boxed` and :func:`wall_before_boxed`."""
    for j in range(near.shape[0]):
        s = near[j]
        boxes[0, j] = min(segs[s, 0], segs[s, 2])
        boxes[1, j] = max(segs[s, 0], segs[s, 2])
        boxes[2, j] = min(segs[s, 1], segs[s, 3])
        boxes[3, j] = max(segs[s, 1], segs[s, 3])


@njit(cache=True, inline="always")
def _boxes_meeting(boxes, m, bx0, bx1, by0, by1, meets):
    """``meets[j]`` for ``j < m``: box ``j`` of ``boxes`` meets the box ``[bx0, bx1] x [by0, by1]`` (the test
    of :func:`segment_hit`'s culling, branch-free over contiguous rows)."""
    for j in range(m):
        meets[j] = not (boxes[0, j] > bx1 or boxes[1, j] < bx0 or boxes[2, j] > by1 or boxes[3, j] < by0)


@njit(cache=True, inline="always")
def segment_hit_boxed(x0, y0, ddx, ddy, segs, idx, boxes, meets, reach):
    """:func:`segment_hit` with ``cull`` (not ``open_end``; ``reach`` finite), the same ``(t, index, d x e)``
    bit for bit, the segments' boxes read from ``boxes`` (:func:`near_boxes` of ``idx``) and tested in one
    pass before any segment's hit; ``meets`` (bool, ``>= len(idx)``) is scratch."""
    fx = x0 + ddx * reach
    fy = y0 + ddy * reach
    m = idx.shape[0]
    _boxes_meeting(boxes, m, min(x0, fx) - _BOX_SLACK, max(x0, fx) + _BOX_SLACK, min(y0, fy) - _BOX_SLACK,
                   max(y0, fy) + _BOX_SLACK, meets)
    best = np.inf
    best_i = -1
    best_den = 0.0
    for j in range(m):
        if not meets[j]:
            continue
        s = idx[j]
        ex = segs[s, 2] - segs[s, 0]
        ey = segs[s, 3] - segs[s, 1]
        den = ddx * ey - ddy * ex
        if not abs(den) > _EPS:
            continue
        wx = segs[s, 0] - x0
        wy = segs[s, 1] - y0
        t = (wx * ey - wy * ex) / den
        u = (wx * ddy - wy * ddx) / den
        if t >= 0.0 and u >= -_EPS and u <= 1.0 + _EPS and t < best:
            best = t
            best_i = s
            best_den = den
    return best, best_i, best_den


@njit(cache=True, inline="always")
def wall_before_boxed(x0, y0, ddx, ddy, segs, idx, boxes, meets, limit, far):
    """:func:`wall_before` (the same answer) with the segments' boxes read from ``boxes`` (:func:`near_boxes`
    of ``idx``) and tested in one pass first; ``meets`` (bool, ``>= len(idx)``) is scratch."""
    fx = x0 + ddx * far
    fy = y0 + ddy * far
    m = idx.shape[0]
    _boxes_meeting(boxes, m, min(x0, fx) - _SIGHT_SLACK, max(x0, fx) + _SIGHT_SLACK, min(y0, fy) - _SIGHT_SLACK,
                   max(y0, fy) + _SIGHT_SLACK, meets)
    for j in range(m):
        if not meets[j]:
            continue
        s = idx[j]
        ex = segs[s, 2] - segs[s, 0]
        ey = segs[s, 3] - segs[s, 1]
        den = ddx * ey - ddy * ex
        if not abs(den) > _EPS:
            continue
        wx = segs[s, 0] - x0
        wy = segs[s, 1] - y0
        t = (wx * ey - wy * ex) / den
        u = (wx * ddy - wy * ddx) / den
        if t >= 0.0 and u >= -_EPS and u <= 1.0 + _EPS and t < limit:
            return True
    return False
