"""Compiled (numba) loops behind :mod:`parcover_env.geometry.rays`; import only through that module
(and the sonar's compiled ring, :mod:`parcover_env.sensors._onboard_kernels`, which calls the sonar
loops from compiled code).

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
def _segment_hit(x0, y0, ddx, ddy, segs, idx, reach, cull, open_end):
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
        best = min(best, _disc_t(b, c))
    return best


@njit(cache=True, inline="always")
def _disc_hit_from(ddx, ddy, ocx, ocy, cc):
    """:func:`_disc_hit` with the origin's disc terms ``oc = o - c`` and ``|oc|^2 - r^2`` computed
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
        t, i, den = _segment_hit(ox[o], oy[o], dx[r], dy[r], segs, every, reach, cull, False)
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
    every = np.arange(segs.shape[0])
    for r in range(ax.shape[0]):
        _, i, _ = _segment_hit(ax[r], ay[r], bx[r] - ax[r], by[r] - ay[r], segs, every, 1.0, True, True)
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
            _, hit, _ = _segment_hit(px[i], py[i], px[j] - px[i], py[j] - py[i], segs, every, 1.0, True, True)
            out[i] = hit >= 0


@njit(cache=True, nogil=True)
def near_segments(ox, oy, segs, reach, idx, cnt):
    """Per origin ``o``, the indices (ascending) of the segments within ``reach`` of it by
    point-to-segment distance: ``idx[o, :cnt[o]]``. A path of rays leaving ``o`` meets no other
    segment within that length, so restricting its casts to the list changes no result."""
    for o in range(ox.shape[0]):
        c = 0
        for s in range(segs.shape[0]):
            ax = segs[s, 0]
            ay = segs[s, 1]
            ex = segs[s, 2] - ax
            ey = segs[s, 3] - ay
            wx = ox[o] - ax
            wy = oy[o] - ay
            ll = ex * ex + ey * ey
            u = min(max((wx * ex + wy * ey) / ll, 0.0), 1.0) if ll > 0.0 else 0.0
            px = wx - u * ex
            py = wy - u * ey
            if px * px + py * py <= reach * reach:
                idx[o, c] = s
                c += 1
        cnt[o] = c


@njit(cache=True, inline="always")
def _incidence(den, seg_len, i):
    """``|cos|`` of the incidence of a hit on segment ``i`` (``den = d x e``; 0 if no hit)."""
    return abs(den) / max(seg_len[i], _COS_FLOOR) if i >= 0 else 0.0


@njit(cache=True, nogil=True)
def sonar_echoes(ox, oy, axes, offsets, segs, seg_len, idx, cnt, cx, cy, r2, owner, rmax,
                 specular, multipath, cos_min, nudge, box_cull, reading):
    """Nearest echo ``reading (N, B)`` over the sub-rays of every beam, inf if none (the rules of
    :func:`parcover_env.sensors.sonar.simulate_beams`). Beam ``b`` of origin ``n`` has the sub-rays
    at angles ``axes[n, b] + offsets[j]``.

    A sub-ray's first hit within ``rmax`` on the walls is ``t1`` (incidence ``|cos| c1``), on the
    discs ``td``. ``specular``: a wall echoes only if ``c1 >= cos_min``; with ``multipath`` an
    oblique wall mirrors the sub-ray, which starts again ``nudge`` off the wall and reads
    ``t1 + t2 + nudge`` if its next surface (a normal-enough wall, or a disc) lies within
    ``rmax - t1`` (``t2 + nudge`` compared). A disc nearer than the wall echoes (``td``). Walls
    are looked up in the origin's list ``idx`` of those within ``rmax`` (plus the nudge;
    :func:`near_segments`): a two-leg path of length <= ``rmax`` stays within it."""
    cull = box_cull and math.isfinite(rmax)
    per_origin = cx.shape[0] > 1
    n_discs = cx.shape[1]
    spread = 0.0  # the sub-rays' largest angle off the beam axis (< pi / 2: cones are < 180 deg)
    for j in range(offsets.shape[0]):
        spread = max(spread, abs(offsets[j]))
    leg_t = np.empty(offsets.shape[0])  # per beam: the sub-rays an oblique wall mirrored
    leg_i = np.empty(offsets.shape[0], dtype=np.int64)
    leg_x = np.empty(offsets.shape[0])
    leg_y = np.empty(offsets.shape[0])
    cos_spread = math.cos(spread)
    sin_spread = math.sin(spread)
    ocx = np.empty(n_discs)  # per origin: the terms of the discs a sub-ray within rmax can hit
    ocy = np.empty(n_discs)
    cc = np.empty(n_discs)
    ux = np.empty(n_discs)
    uy = np.empty(n_discs)
    cos_w = np.empty(n_discs)
    bx = np.empty(n_discs)  # per beam: those a sub-ray of its cone can hit
    by = np.empty(n_discs)
    bc = np.empty(n_discs)
    for n in range(ox.shape[0]):
        x0 = ox[n]
        y0 = oy[n]
        row = n if per_origin else 0
        near = idx[n, :cnt[n]]
        m = _near_discs(x0, y0, cx[row], cy[row], r2, owner[n], rmax, cos_spread, sin_spread, ocx, ocy, cc, ux, uy,
                        cos_w)
        for b in range(axes.shape[1]):
            ax = math.cos(axes[n, b])
            ay = math.sin(axes[n, b])
            nb = 0
            for d in range(m):
                if ax * ux[d] + ay * uy[d] >= cos_w[d]:
                    bx[nb] = ocx[d]
                    by[nb] = ocy[d]
                    bc[nb] = cc[d]
                    nb += 1
            best = np.inf
            n_legs = 0
            for j in range(offsets.shape[0]):  # first legs: direct echoes (walls near the normal, discs)
                ang = axes[n, b] + offsets[j]
                ddx = math.cos(ang)
                ddy = math.sin(ang)
                # an echo is never nearer than the sub-ray's first wall or disc, so walls beyond the
                # cone's nearest echo so far (``best``) are culled and mirrored legs from there skipped
                t1, i1, den = _segment_hit(x0, y0, ddx, ddy, segs, near, min(rmax, best), cull, False)
                td = _disc_hit_from(ddx, ddy, bx[:nb], by[:nb], bc[:nb])
                if not td <= rmax:
                    td = np.inf
                if not (i1 >= 0 and t1 <= rmax):
                    t1 = np.inf
                    i1 = -1
                if not specular:
                    echo = min(t1, td)
                elif td < t1:
                    echo = td
                elif _incidence(den, seg_len, i1) >= cos_min:
                    echo = t1
                else:
                    echo = np.inf
                    if multipath and i1 >= 0:  # mirrored by an oblique wall: its second leg comes after
                        leg_t[n_legs] = t1
                        leg_i[n_legs] = i1
                        leg_x[n_legs] = ddx
                        leg_y[n_legs] = ddy
                        n_legs += 1
                best = min(best, echo)
            for k in range(n_legs):  # second legs, once the cone's direct echoes bound what can be nearer
                if leg_t[k] < best:
                    echo = _second_leg(x0, y0, leg_x[k], leg_y[k], leg_t[k], leg_i[k], segs, seg_len, near, cx, cy,
                                       row, r2, owner[n], rmax, cos_min, nudge, box_cull)
                    best = min(best, echo)
            reading[n, b] = best


_DISC_SLACK = 1e-6
"""Margin (m, rad) of the disc culls of :func:`sonar_echoes`: rounding never culls a disc a sub-ray hits."""


@njit(cache=True, inline="always")
def _near_discs(x0, y0, cx, cy, r2, mine, rmax, cos_spread, sin_spread, ocx, ocy, cc, ux, uy, cos_w):
    """The discs ``cx, cy`` (squared radii ``r2``) but ``mine`` that a ray from ``(x0, y0)`` can hit
    within ``rmax``, compacted into the first ``m`` entries of the outputs (``m`` returned): the
    terms ``oc = o - c`` and ``|oc|^2 - r^2`` of :func:`_disc_hit_from`, the unit vector ``u`` to the
    centre and the cosine of ``spread`` (< pi / 2; given as its cosine and sine) plus the half-angle
    the disc spans (-2 if the origin is inside it: every ray hits). A ray hits a disc outside it only
    within that half-angle of ``u`` (at a distance >= ``|oc| - r``), so a cone of half-angle
    ``spread`` about a unit axis ``a`` can hit it only if ``a . u >= cos_w``."""
    m = 0
    for d in range(cx.shape[0]):
        if d == mine:
            continue
        dx = x0 - cx[d]
        dy = y0 - cy[d]
        c = (dx * dx + dy * dy) - r2[d]
        if c > 0.0:
            dist = math.sqrt(dx * dx + dy * dy)
            r = math.sqrt(r2[d])
            if dist - r > rmax + _DISC_SLACK:
                continue
            ux[m] = -dx / dist
            uy[m] = -dy / dist
            sin_w = min(r / dist, 1.0)  # cos(spread + w), w the disc's half-angle, minus a rounding margin
            cos_w[m] = cos_spread * math.sqrt(1.0 - sin_w * sin_w) - sin_spread * sin_w - _DISC_SLACK
        else:
            ux[m] = 0.0
            uy[m] = 0.0
            cos_w[m] = -2.0
        ocx[m] = dx
        ocy[m] = dy
        cc[m] = c
        m += 1
    return m


@njit(cache=True, inline="always")
def _second_leg(x0, y0, ddx, ddy, t1, i1, segs, seg_len, near, cx, cy, row, r2, mine, rmax, cos_min, nudge,
                box_cull):
    """Echo length ``t1 + t2`` of a sub-ray mirrored at ``t1`` by segment ``i1``, inf if its second
    leg finds no echoing surface within ``rmax - t1``."""
    ex = segs[i1, 2] - segs[i1, 0]
    ey = segs[i1, 3] - segs[i1, 1]
    norm = math.sqrt(ex * ex + ey * ey)
    nx = -ey / norm
    ny = ex / norm
    f = 2.0 * (ddx * nx + ddy * ny)
    d2x = ddx - f * nx
    d2y = ddy - f * ny
    px = (x0 + ddx * t1) + d2x * nudge
    py = (y0 + ddy * t1) + d2y * nudge
    reach = rmax - t1
    t2w, i2, den2 = _segment_hit(px, py, d2x, d2y, segs, near, reach, box_cull and math.isfinite(reach), False)
    if not (i2 >= 0 and t2w <= reach):
        t2w = np.inf
        i2 = -1
    wall2 = t2w if _incidence(den2, seg_len, i2) >= cos_min else np.inf
    td2 = _disc_hit(px, py, d2x, d2y, cx, cy, row, r2, mine)
    t2 = (td2 if td2 < t2w else wall2) + nudge
    return t1 + t2 if t2 <= rmax - t1 else np.inf


@njit(cache=True, inline="always")
def _wrap(a):
    """``a`` wrapped to (-pi, pi], as :func:`parcover_env.geometry.angles.wrap_angle`."""
    return math.pi - ((math.pi - a) % (2.0 * math.pi))


@njit(cache=True, inline="always")
def _in_cone(a, half):
    """``|wrap(a)| <= half``, exactly; a cheap rounding-based wrap first rejects angles clearly
    outside (it agrees with :func:`_wrap` to ~1e-15 rad, far below the 1e-9 rad margin)."""
    if abs(a - 2.0 * math.pi * round(a / (2.0 * math.pi))) > half + 1e-9:
        return False
    return abs(_wrap(a)) <= half


@njit(cache=True, nogil=True)
def sonar_corner_echoes(ox, oy, axes, pts, u1, u2, segs, idx, cnt, cx, cy, r2, owner, rmax, half, reading):
    """Lower ``reading (N, B)`` to the distance of every concave corner ``pts (C, 2)`` (wall
    directions ``u1, u2``) that origin ``n`` sees from inside the corner's wedge, within ``rmax``,
    with no wall (nor disc) in between, and inside beam ``b``'s cone (``|bearing - axis| <= half``);
    the concave-corner rule of :func:`parcover_env.sensors.sonar.simulate_beams`. Walls are looked
    up in the origin's list ``idx`` of those within ``rmax`` (:func:`near_segments`)."""
    has_discs = cx.shape[1] > 0
    per_origin = cx.shape[0] > 1
    for n in range(ox.shape[0]):
        x0 = ox[n]
        y0 = oy[n]
        near = idx[n, :cnt[n]]
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
            bearing = math.atan2(vy, vx)
            seen = -1  # line of sight: unknown until a beam's cone holds the corner
            for b in range(axes.shape[1]):
                if not (dist < reading[n, b] and _in_cone(bearing - axes[n, b], half)):
                    continue
                if seen < 0:
                    dx = vx / dist
                    dy = vy / dist
                    t, _, _ = _segment_hit(x0, y0, dx, dy, segs, near, np.inf, False, False)
                    seen = 1 if t >= dist * (1.0 - 1e-7) - 1e-9 else 0  # else a wall in between
                    if seen and has_discs and not _disc_hit(x0, y0, dx, dy, cx, cy, n if per_origin else 0, r2,
                                                            owner[n]) >= dist:
                        seen = 0  # a robot in between
                if seen:
                    reading[n, b] = dist


@njit(cache=True, nogil=True)
def sonar_crosstalk(px, py, pth, beams, all_round, segs, idx, cnt, half, rmax, want, out):
    """Cross-talk readings ``out (K, N, B)`` (left inf where none) of robots ``(K, N)`` poses
    ``px, py, pth``: beam ``b`` of robot ``i`` reads ``d / 2`` from the nearest robot ``j`` of its world
    inside that beam's cone (``half``) with a beam of ``j`` pointing back at ``i``, ``0 < d / 2 <= rmax``
    and no wall between them; the rules of :func:`parcover_env.sensors.sonar.crosstalk`.
    ``all_round``: the cones cover every direction (a beam always points back). Walls are looked up
    in robot ``k * N + i``'s list ``idx`` of those within ``2 rmax`` (:func:`near_segments`).
    Only the beams ``want (K, N, B)`` are computed (the others stay inf)."""
    nb = beams.shape[0]
    n_robots = px.shape[1]
    for k in range(px.shape[0]):
        for i in range(n_robots):
            wanted = False
            for b in range(nb):
                wanted = wanted or want[k, i, b]
            if not wanted:
                continue
            near = idx[k * n_robots + i, :cnt[k * n_robots + i]]
            for j in range(n_robots):
                if i == j:
                    continue
                dx = px[k, j] - px[k, i]
                dy = py[k, j] - py[k, i]
                d = math.hypot(dx, dy)
                if not (d / 2 <= rmax and d > 0):
                    continue
                bearing = math.atan2(dy, dx)
                gain = False  # does a beam of i hold j nearer than what it heard so far?
                for b in range(nb):
                    if want[k, i, b] and d / 2 < out[k, i, b] and _in_cone(bearing - pth[k, i] - beams[b], half):
                        gain = True
                        break
                if not gain:
                    continue
                back = all_round
                for c in range(0 if all_round else nb):
                    if _in_cone(bearing + math.pi - pth[k, j] - beams[c], half):
                        back = True
                        break
                if not back:
                    continue
                _, hit, _ = _segment_hit(px[k, i], py[k, i], dx, dy, segs, near, 1.0, True, True)
                if hit >= 0:
                    continue  # a wall between them
                for b in range(nb):
                    if want[k, i, b] and d / 2 < out[k, i, b] and _in_cone(bearing - pth[k, i] - beams[b], half):
                        out[k, i, b] = d / 2
