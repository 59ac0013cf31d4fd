"""Compiled (numba) echoes of the sonar, the internals of :mod:`parcover_env.sensors.sonar` (public
so that tests and other rooms may use them): the specular cone with its second legs, robots and
concave corners, noise-free. Cross-talk, noise and the whole ring of every robot of K worlds in one
call build on them in :mod:`parcover_env.sensors.sonar_ring_kernels`. They cast rays with the
per-ray helpers of :mod:`parcover_env.geometry.ray_kernels` (same float operations, no fast-math).

The kernels read their constants from a :data:`SONAR_RULES` record (a structured array,
:mod:`parcover_env.geometry.records`: ``rules[0].range_max``, never ``par[0]``) and take bundles of
arrays as the ``NamedTuple`` classes below. ``tests/references/sonar.py`` keeps the plain-Python
references.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.geometry.angle_kernels import wrap
from parcover_env.geometry.ray_kernels import (
    COS_FLOOR,
    disc_fan,
    disc_hit,
    in_cone,
    near_boxes,
    near_segments,
    segment_fan,
    segment_fan_spans,
    segment_hit,
    segment_hit_boxed,
    wall_before_boxed,
)

__all__ = ["SONAR_RULES", "WallSet", "wall_set", "Discs", "sonar_echoes", "sonar_corner_echoes", "beam_readings"]

SONAR_RULES = np.dtype([
    ("range_max", "f8"),  # a path longer than this returns nothing; no echo reads this (m)
    ("specular", "?"),  # walls echo only near the normal (if there are walls), else every hit echoes
    ("multipath", "?"),  # an oblique wall mirrors the sub-ray, which may echo off the next surface
    ("cos_min", "f8"),  # smallest |cos| of incidence at which a wall echoes
    ("nudge", "f8"),  # a mirrored sub-ray starts this far off the wall it left (m)
    ("box_cull", "?"),  # box-cull the walls of a cast (never changes a result)
    ("half_cone", "f8"),  # half the beam's cone, with a rounding slack (rad)
    ("all_round", "?"),  # the ring's cones cover every direction (a robot's beam always points back)
    ("near_slack", "f8"),  # slack added to a near-wall list's reach (m)
    ("crosstalk_prob", "f8"),  # probability that a beam facing a robot that pings back hears it
    ("range_min", "f8"),  # (m)
    ("drop_below", "?"),  # echoes nearer than range_min are lost (else clipped to it)
    ("noise_std", "f8"),  # Gaussian noise sigma (m) ...
    ("noise_rel", "f8"),  # ... plus this times the range
    ("quantization", "f8"),  # echoes are rounded to multiples of this (m); 0: not
    ("garbage_rate", "f8"),  # probability of a reading uniform in [range_min, range_max]
    ("dropout_prob", "f8"),  # fast model: probability that an echo is lost (reads range_max)
])
"""Every constant of the compiled sonar, one record (:func:`parcover_env.geometry.records.record`)."""


class WallSet(NamedTuple):
    """The walls a ring sees and their corners."""

    segments: np.ndarray
    """``(S, 4)`` float64 C-contiguous rows ``(x1, y1, x2, y2)`` (m)."""
    lengths: np.ndarray
    """``(S,)`` length of each segment (m)."""
    points: np.ndarray
    """``(C, 2)`` corner vertices (:func:`parcover_env.sensors.sonar.concave_corners`) (m)."""
    u1: np.ndarray
    """``(C, 2)`` unit direction of a corner's first wall."""
    u2: np.ndarray
    """``(C, 2)`` unit direction of its second wall."""
    owned: np.ndarray
    """``(S, 2)`` int64: the corners listed at each segment (-1: none), each corner at the first
    (lowest index) of its two walls, so that the corners within a range are found from the walls
    within it (a corner lies on both of its walls)."""


def wall_set(segs: np.ndarray) -> WallSet:
    """The :class:`WallSet` of ``segs (S, 4)`` (float64, C-contiguous, read-only: kept as is): the
    lengths, and the vertices shared by exactly two non-collinear segments (ends rounded to 1e-9 m)
    with their unit wall directions, each listed at the first of its two walls (``owned``)."""
    n = len(segs)
    lengths = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    # the ends rounded as numpy rounds a float64 scalar (``round(np.float64, 9)``), all at once; the
    # first end of each vertex keeps its key (and the sign of a zero), as a dict does
    rounded = np.round(segs, 9).tolist()
    ends: dict[tuple[float, float], list[tuple[float, float, int]]] = {}  # vertex: (other end, segment index)
    for i, (x1, y1, x2, y2) in enumerate(rounded):
        a, b = (x1, y1), (x2, y2)
        if a == b:
            continue
        ends.setdefault(a, []).append((x2, y2, i))
        ends.setdefault(b, []).append((x1, y1, i))
    # vertices shared by exactly two segments, in the order the dict met them: their wall directions
    # normalized as ``u / np.linalg.norm(u)`` does (``sqrt(u.dot(u))``), collinear pairs dropped
    pairs = [(v, o[0], o[1]) for v, o in ends.items() if len(o) == 2]
    owned = np.full((n, 2), -1, dtype=np.int64)  # a corner is listed at the first of its two walls
    corners = (np.zeros((0, 2)),) * 3
    if pairs:
        vv = np.array([v for v, _, _ in pairs])
        u1 = np.array([e1[:2] for _, e1, _ in pairs]) - vv
        u2 = np.array([e2[:2] for _, _, e2 in pairs]) - vv
        u1 = u1 / np.sqrt(np.array([u.dot(u) for u in u1]))[:, None]
        u2 = u2 / np.sqrt(np.array([u.dot(u) for u in u2]))[:, None]
        corner = ~(np.abs(u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0]) < 1e-9)  # collinear: not a corner
        for c, k in enumerate(np.flatnonzero(corner).tolist()):
            first = min(pairs[k][1][2], pairs[k][2][2])
            owned[first, int(owned[first, 0] >= 0)] = c
        if corner.any():
            corners = (vv[corner], u1[corner], u2[corner])
    for a in (lengths, *corners, owned):
        a.setflags(write=False)
    return WallSet(segs, lengths, *corners, owned)


class Discs(NamedTuple):
    """Robot discs that block and echo, as :func:`parcover_env.geometry.rays.disc_planes` lays them out."""

    cx: np.ndarray
    """``(C, D)`` centres' x: row ``o`` for origin ``o`` if ``C > 1`` (a set per origin), else row 0 (m)."""
    cy: np.ndarray
    """``(C, D)`` centres' y (m)."""
    r2: np.ndarray
    """``(D,)`` squared radii (m^2)."""
    owner: np.ndarray
    """``(N,)`` int64: the disc of origin ``o`` itself (never hit), -1 if none."""


class _DiscTerms(NamedTuple):
    """Per origin, the terms of the discs a sub-ray can hit (:func:`_near_discs`), compacted first."""

    ocx: np.ndarray
    ocy: np.ndarray
    cc: np.ndarray
    cx: np.ndarray
    """``(1, D)``: the discs' centres and squared radii, for the second legs (:func:`_second_leg`)."""
    cy: np.ndarray
    r2: np.ndarray


@njit(cache=True, inline="always")
def _incidence(den, seg_len, i):
    """``|cos|`` of the incidence of a hit on segment ``i`` (``den = d x e``; 0 if no hit)."""
    return abs(den) / max(seg_len[i], COS_FLOOR) if i >= 0 else 0.0


class DiscRow(NamedTuple):
    """The discs one origin sees: row ``row`` of the :class:`Discs` centres ``cx, cy (C, D)``, squared radii
    ``r2 (D,)``, all but its own disc ``mine`` (-1: none)."""

    cx: np.ndarray
    cy: np.ndarray
    row: int
    r2: np.ndarray
    mine: int


class LegCull(NamedTuple):
    """How :func:`_second_leg` culls: only as far as ``bound`` (inf: ``rmax``), and with the near walls' boxes
    (:func:`~parcover_env.geometry.ray_kernels.near_boxes` in ``boxes``, ``meets`` scratch) if ``boxed``."""

    bound: float
    boxes: np.ndarray
    meets: np.ndarray
    boxed: bool


class WallBoxes(NamedTuple):
    """The near walls' boxes ``(4, S)`` (:func:`~parcover_env.geometry.ray_kernels.near_boxes`) and ``(S,)``
    bool scratch for the sight lines of :func:`origin_corners`."""

    boxes: np.ndarray
    meets: np.ndarray


class EchoScratch(NamedTuple):
    """The scratch arrays of :func:`sonar_echoes`' steps for one origin (:func:`echo_scratch`), reused origin
    after origin: the traced sub-rays' directions and first hits, each sub-ray's direct echo and mirror,
    the near walls' boxes and the discs' terms."""

    slot: np.ndarray
    """``(B * J,)`` int64: the traced index of each pair that traces its direction."""
    co: np.ndarray
    """``(J,)`` cosines and sines of the sub-ray offsets."""
    so: np.ndarray
    fdx: np.ndarray
    """``(T,)`` the traced sub-rays' unit directions, first wall hits (``t``, wall, ``d x e``) and disc hits."""
    fdy: np.ndarray
    fan_t: np.ndarray
    fan_i: np.ndarray
    fan_den: np.ndarray
    fan_td: np.ndarray
    fan_order: np.ndarray
    """``(T,)`` :func:`~parcover_env.geometry.ray_kernels.segment_fan_spans`' ray order (kept between origins)."""
    fan_keys: np.ndarray
    no_boxes: np.ndarray
    """``(0, T)``: :func:`~parcover_env.geometry.ray_kernels.segment_fan` without culling."""
    direct: np.ndarray
    """``(B * J,)`` per traced pair: its direct echo (inf if none), where an oblique wall mirrored it
    (``leg_t``, inf: not mirrored; ``leg_i``, ``leg_x``, ``leg_y``), its two-leg echo (nan: not traced yet)
    and the bound it was traced for (:func:`_second_leg`)."""
    leg_t: np.ndarray
    leg_i: np.ndarray
    leg_x: np.ndarray
    leg_y: np.ndarray
    leg_echo: np.ndarray
    leg_bound: np.ndarray
    legs: np.ndarray
    """``(J,)`` int64: a beam's sub-rays, nearest mirror first."""
    boxes: np.ndarray
    """``(4, S)`` the near walls' bounding boxes (the second legs' culls) and ``(S,)`` bool scratch."""
    meets: np.ndarray
    terms: _DiscTerms
    """The terms of the discs a sub-ray within ``rmax`` can hit (:func:`_near_discs`)."""
    normals: np.ndarray
    """``(S, 2)`` the walls' unit normals."""


@njit(cache=True)
def echo_scratch(offsets, share, segs, n_discs):
    """The :class:`EchoScratch` of beams whose sub-rays are shared as ``share (B, J)`` (offsets ``(J,)``), among
    the walls ``segs (S, 4)`` and ``n_discs`` discs."""
    n_sub = offsets.shape[0]
    n_pairs = share.shape[0] * n_sub
    slot = np.empty(n_pairs, dtype=np.int64)  # the traced sub-rays (a direction's first pair), in order
    n_traced = 0
    for b in range(share.shape[0]):
        for j in range(n_sub):
            if share[b, j] == b * n_sub + j:
                slot[b * n_sub + j] = n_traced
                n_traced += 1
    terms = _DiscTerms(np.empty(n_discs), np.empty(n_discs), np.empty(n_discs), np.empty((1, n_discs)),
                       np.empty((1, n_discs)), np.empty(n_discs))
    return EchoScratch(
        slot=slot, co=np.cos(offsets), so=np.sin(offsets), fdx=np.empty(n_traced), fdy=np.empty(n_traced),
        fan_t=np.empty(n_traced), fan_i=np.empty(n_traced, dtype=np.int64), fan_den=np.empty(n_traced),
        fan_td=np.empty(n_traced), fan_order=np.arange(n_traced), fan_keys=np.empty(n_traced),
        no_boxes=np.empty((0, n_traced)), direct=np.empty(n_pairs), leg_t=np.empty(n_pairs),
        leg_i=np.empty(n_pairs, dtype=np.int64), leg_x=np.empty(n_pairs), leg_y=np.empty(n_pairs),
        leg_echo=np.empty(n_pairs), leg_bound=np.empty(n_pairs), legs=np.empty(n_sub, dtype=np.int64),
        boxes=np.empty((4, segs.shape[0])), meets=np.empty(segs.shape[0], dtype=np.bool_), terms=terms,
        normals=_normals(segs))


@njit(cache=True, nogil=True)
def origin_first_legs(x0, y0, axes, share, walls, near, seen, rules, sc, best, mirror):
    """:func:`sonar_echoes`' first step for the origin ``(x0, y0)`` with beam axes ``axes (B,)``, near walls
    ``near`` and the discs it sees (a :class:`DiscRow` ``seen``): each traced sub-ray's first hits (one fan)
    and direct echo, into the :class:`EchoScratch` ``sc``; per beam ``b``, ``best[b]`` = its cone's nearest
    direct echo (inf if none) and ``mirror[b]`` = the nearest first leg of its sub-rays that an oblique wall
    mirrored (inf if none: the beam's echo lies between ``min(best, mirror)`` and ``best``). Returns how
    many discs a second leg may meet (the first of ``sc.terms``)."""
    segs, seg_len = walls.segments, walls.lengths
    rule = rules[0]
    rmax, multipath, cos_min = rule.range_max, rule.multipath, rule.cos_min
    specular = rule.specular and segs.shape[0] > 0
    n_sub = sc.co.shape[0]
    slot, fdx, fdy, co, so = sc.slot, sc.fdx, sc.fdy, sc.co, sc.so
    fan_t, fan_i, fan_den, fan_td = sc.fan_t, sc.fan_i, sc.fan_den, sc.fan_td
    direct, leg_echo, leg_i, leg_x, leg_y = sc.direct, sc.leg_echo, sc.leg_i, sc.leg_x, sc.leg_y
    if fdx.shape[0] >= FAN_SPANS_MIN:  # a scan's many second legs test the near walls' boxes (_second_leg)
        near_boxes(segs, near, sc.boxes)
    m = _near_discs(x0, y0, seen.cx[seen.row], seen.cy[seen.row], seen.r2, seen.mine, rmax, sc.terms)
    for b in range(axes.shape[0]):
        ax = math.cos(axes[b])
        ay = math.sin(axes[b])
        for j in range(n_sub):
            if share[b, j] == b * n_sub + j:
                p = slot[b * n_sub + j]
                fdx[p] = ax * co[j] - ay * so[j]
                fdy[p] = ay * co[j] + ax * so[j]
    # first hits of every traced sub-ray at once (no cull: a hit within rmax is the same, and one
    # beyond rmax, or beyond a cone's nearest echo, never changes a reading)
    if fdx.shape[0] >= FAN_SPANS_MIN and near.shape[0] >= FAN_SPANS_WALLS:
        segment_fan_spans(x0, y0, fdx, fdy, segs, near, sc.fan_order, sc.fan_keys, fan_t, fan_i, fan_den)
    else:
        segment_fan(x0, y0, fdx, fdy, segs, near, sc.no_boxes, fan_t, fan_i, fan_den)
    fan_td[:] = np.inf
    disc_fan(fdx, fdy, sc.terms.ocx[:m], sc.terms.ocy[:m], sc.terms.cc[:m], fan_td)
    leg_t = sc.leg_t
    for b in range(axes.shape[0]):
        near_echo = np.inf
        near_mirror = np.inf
        for j in range(n_sub):  # first legs: direct echoes (walls near the normal, discs)
            u = share[b, j]
            if u == b * n_sub + j:  # a direction not traced yet
                p = slot[u]
                t1, i1, den, td = fan_t[p], fan_i[p], fan_den[p], fan_td[p]
                if not td <= rmax:
                    td = np.inf
                if not (i1 >= 0 and t1 <= rmax):
                    t1 = np.inf
                    i1 = -1
                leg_t[u] = np.inf
                leg_echo[u] = np.nan
                if not specular:
                    echo = min(t1, td)
                elif td < t1:
                    echo = td
                elif _incidence(den, seg_len, i1) >= cos_min:
                    echo = t1
                else:
                    echo = np.inf
                    if multipath and i1 >= 0:  # mirrored by an oblique wall: its second leg comes after
                        leg_t[u] = t1
                        leg_i[u] = i1
                        leg_x[u] = fdx[p]
                        leg_y[u] = fdy[p]
                direct[u] = echo
            near_echo = min(near_echo, direct[u])
            near_mirror = min(near_mirror, leg_t[u])
        best[b] = near_echo
        mirror[b] = near_mirror
    return m


@njit(cache=True, nogil=True)
def origin_second_legs(x0, y0, share, walls, near, m, owner, rules, sc, best, mirror):
    """:func:`sonar_echoes`' second step for the origin of :func:`origin_first_legs` (``sc``, ``m`` discs): each
    beam ``b``'s reading into ``best[b]``, the nearest of ``best[b]`` (at least its cone's nearest direct echo,
    at most the reading without second legs: e.g. lowered by a corner) and its sub-rays' two-leg echoes,
    nearest mirror first (a leg reads more than its first leg, so one that starts beyond the best echo so far
    cannot lower it), each traced only as far as that best (``leg_bound``: the best it was traced for; a leg
    traced for a bound B reads its own echo, or something above B when its echo lies above B: the minimum with
    any best <= B is the same). ``mirror``: :func:`origin_first_legs`' nearest first leg of each beam's mirrored
    sub-rays (a beam whose ``mirror`` is not below its best has nothing to trace). One call per origin (the
    scratch is passed once, not per beam)."""
    n_sub = sc.co.shape[0]
    legs, leg_t, leg_echo, leg_bound = sc.legs, sc.leg_t, sc.leg_echo, sc.leg_bound
    leg_x, leg_y, leg_i, normals, boxes, meets = sc.leg_x, sc.leg_y, sc.leg_i, sc.normals, sc.boxes, sc.meets
    leg_discs = Discs(sc.terms.cx[:, :m], sc.terms.cy[:, :m], sc.terms.r2[:m], owner)  # legs stay within rmax
    wide = sc.fdx.shape[0] >= FAN_SPANS_MIN  # a scan: legs nearest first, bounded, boxes (a ring: as they come)
    for b in range(best.shape[0]):
        if not mirror[b] < best[b]:  # no sub-ray mirrored before the best echo: no leg can lower it
            continue
        for j in range(n_sub):
            legs[j] = share[b, j]
        for j in range(1, n_sub if wide else 0):  # insertion sort by the first leg's length (5 sub-rays)
            v = legs[j]
            k = j - 1
            while k >= 0 and leg_t[legs[k]] > leg_t[v]:
                legs[k + 1] = legs[k]
                k -= 1
            legs[k + 1] = v
        near_best = best[b]
        for j in range(n_sub):
            u = legs[j]
            if not leg_t[u] < near_best:
                if wide:
                    break
                continue
            if math.isnan(leg_echo[u]) or near_best > leg_bound[u]:
                bound = near_best if wide else np.inf
                leg_echo[u] = _second_leg(x0, y0, leg_x[u], leg_y[u], leg_t[u], leg_i[u], walls, normals, near,
                                          leg_discs, rules, LegCull(bound, boxes, meets, wide))
                leg_bound[u] = bound
            near_best = min(near_best, leg_echo[u])
        best[b] = near_best


@njit(cache=True, nogil=True)
def sonar_echoes(ox, oy, axes, offsets, share, walls, idx, cnt, discs, rules, reading):
    """Nearest echo ``reading (N, B)`` over the sub-rays of every beam, inf if none (the rules of
    :func:`parcover_env.sensors.sonar.simulate_beams`), from origins ``ox, oy (N,)`` among the
    :class:`WallSet` and the :class:`Discs`, with the :data:`SONAR_RULES` ``rules`` (specular only if
    there are walls). Beam ``b`` of origin ``n`` has the sub-rays at angles ``axes[n, b] +
    offsets[j]``: the axis's unit vector ``(cos, sin)(axes[n, b])`` rotated by ``offsets[j]`` (two
    sines and cosines per beam, not per sub-ray). Overlapping cones share sub-rays: ``share[b, j]``
    is the flat index ``b' * J + j'`` (``b' * J + j' <= b * J + j``) of the sub-ray traced for that
    pair, its own index the first time a direction comes up.

    A sub-ray's first hit within ``rmax`` on the walls is ``t1`` (incidence ``|cos| c1``), on the
    discs ``td``. ``specular``: a wall echoes only if ``c1 >= cos_min``; with ``multipath`` an
    oblique wall mirrors the sub-ray, which starts again ``nudge`` off the wall and reads
    ``t1 + t2 + nudge`` if its next surface (a normal-enough wall, or a disc) lies within
    ``rmax - t1`` (``t2 + nudge`` compared). A disc nearer than the wall echoes (``td``). Walls
    are looked up in the origin's list ``idx`` of those within ``rmax`` (plus the nudge;
    :func:`near_segments`): a two-leg path of length <= ``rmax`` stays within it, ``idx[n, :cnt[n]]``."""
    segs, seg_len = walls.segments, walls.lengths
    cx, cy, r2, owner = discs.cx, discs.cy, discs.r2, discs.owner
    rule = rules[0]
    rmax, multipath, cos_min = rule.range_max, rule.multipath, rule.cos_min
    specular = rule.specular and segs.shape[0] > 0
    per_origin = cx.shape[0] > 1
    n_discs = cx.shape[1]
    n_sub = offsets.shape[0]
    co = np.cos(offsets)
    so = np.sin(offsets)
    n_pairs = share.shape[0] * n_sub
    slot = np.empty(n_pairs, dtype=np.int64)  # the traced sub-rays (a direction's first pair), in order
    n_traced = 0
    for b in range(share.shape[0]):
        for j in range(n_sub):
            if share[b, j] == b * n_sub + j:
                slot[b * n_sub + j] = n_traced
                n_traced += 1
    fdx = np.empty(n_traced)  # per origin: the traced sub-rays as one fan, their first wall and disc hits
    fdy = np.empty(n_traced)
    fan_t = np.empty(n_traced)
    fan_i = np.empty(n_traced, dtype=np.int64)
    fan_den = np.empty(n_traced)
    fan_td = np.empty(n_traced)
    no_boxes = np.empty((0, n_traced))  # segment_fan without culling
    wide = n_traced >= FAN_SPANS_MIN  # a wide fan (a 360-degree scan): spans, boxes, legs nearest first and bounded
    fan_order = np.arange(n_traced)  # segment_fan_spans' ray order, kept from one origin to the next
    fan_keys = np.empty(n_traced)
    direct = np.empty(n_pairs)  # per origin, per sub-ray traced: its direct echo (inf if none)
    leg_t = np.empty(n_pairs)  # where an oblique wall mirrored it (inf: not mirrored)
    leg_i = np.empty(n_pairs, dtype=np.int64)
    leg_x = np.empty(n_pairs)
    leg_y = np.empty(n_pairs)
    leg_echo = np.empty(n_pairs)  # its two-leg echo, once traced (nan: not yet)
    leg_bound = np.empty(n_pairs)  # the best echo it was traced for (_second_leg's bound)
    legs = np.empty(n_sub, dtype=np.int64)  # a beam's sub-rays, nearest mirror first
    boxes = np.empty((4, segs.shape[0]))  # per origin: the near walls' bounding boxes (the second legs' culls)
    meets = np.empty(segs.shape[0], dtype=np.bool_)
    ocx = np.empty(n_discs)  # per origin: the terms of the discs a sub-ray within rmax can hit
    ocy = np.empty(n_discs)
    cc = np.empty(n_discs)
    terms = _DiscTerms(ocx, ocy, cc, np.empty((1, n_discs)), np.empty((1, n_discs)), np.empty(n_discs))
    normals = _normals(segs)
    for n in range(ox.shape[0]):
        x0 = ox[n]
        y0 = oy[n]
        row = n if per_origin else 0
        near = idx[n, :cnt[n]]
        if wide:
            near_boxes(segs, near, boxes)
        m = _near_discs(x0, y0, cx[row], cy[row], r2, owner[n], rmax, terms)
        leg_discs = Discs(terms.cx[:, :m], terms.cy[:, :m], terms.r2[:m], owner)  # a second leg stays within rmax
        for b in range(axes.shape[1]):
            ax = math.cos(axes[n, b])
            ay = math.sin(axes[n, b])
            for j in range(n_sub):
                if share[b, j] == b * n_sub + j:
                    p = slot[b * n_sub + j]
                    fdx[p] = ax * co[j] - ay * so[j]
                    fdy[p] = ay * co[j] + ax * so[j]
        # first hits of every traced sub-ray at once (no cull: a hit within rmax is the same, and one
        # beyond rmax, or beyond a cone's nearest echo, never changes a reading)
        if wide and near.shape[0] >= FAN_SPANS_WALLS:
            segment_fan_spans(x0, y0, fdx, fdy, segs, near, fan_order, fan_keys, fan_t, fan_i, fan_den)
        else:
            segment_fan(x0, y0, fdx, fdy, segs, near, no_boxes, fan_t, fan_i, fan_den)
        fan_td[:] = np.inf
        disc_fan(fdx, fdy, ocx[:m], ocy[:m], cc[:m], fan_td)
        for b in range(axes.shape[1]):
            best = np.inf
            for j in range(n_sub):  # first legs: direct echoes (walls near the normal, discs)
                u = share[b, j]
                if u == b * n_sub + j:  # a direction not traced yet
                    p = slot[u]
                    t1, i1, den, td = fan_t[p], fan_i[p], fan_den[p], fan_td[p]
                    if not td <= rmax:
                        td = np.inf
                    if not (i1 >= 0 and t1 <= rmax):
                        t1 = np.inf
                        i1 = -1
                    leg_t[u] = np.inf
                    leg_echo[u] = np.nan
                    if not specular:
                        echo = min(t1, td)
                    elif td < t1:
                        echo = td
                    elif _incidence(den, seg_len, i1) >= cos_min:
                        echo = t1
                    else:
                        echo = np.inf
                        if multipath and i1 >= 0:  # mirrored by an oblique wall: its second leg comes after
                            leg_t[u] = t1
                            leg_i[u] = i1
                            leg_x[u] = fdx[p]
                            leg_y[u] = fdy[p]
                    direct[u] = echo
                best = min(best, direct[u])
            # second legs, once the cone's direct echoes bound what can be nearer (origin_second_legs: on a wide
            # fan nearest mirror first, each traced only as far as the best echo so far, walls' boxes first)
            for j in range(n_sub):
                legs[j] = share[b, j]
            for j in range(1, n_sub if wide else 0):  # insertion sort by the first leg's length (5 sub-rays)
                v = legs[j]
                k = j - 1
                while k >= 0 and leg_t[legs[k]] > leg_t[v]:
                    legs[k + 1] = legs[k]
                    k -= 1
                legs[k + 1] = v
            for j in range(n_sub):
                u = legs[j]
                if not leg_t[u] < best:
                    if wide:
                        break
                    continue
                if math.isnan(leg_echo[u]) or best > leg_bound[u]:
                    bound = best if wide else np.inf
                    leg_echo[u] = _second_leg(x0, y0, leg_x[u], leg_y[u], leg_t[u], leg_i[u], walls, normals, near,
                                              leg_discs, rules, LegCull(bound, boxes, meets, wide))
                    leg_bound[u] = bound
                best = min(best, leg_echo[u])
            reading[n, b] = best


_LEG_MARGIN = 1e-9
"""Margin (m) beyond a bound that :func:`_second_leg` traces a second leg: far above the rounding of
``t1 + t2`` (~1e-15 m), so a wall left out lies above the bound in the sum as well."""
FAN_SPANS_MIN = 64
"""From this many traced sub-rays per origin (a 360-degree scan: 144) and :data:`FAN_SPANS_WALLS` near walls,
:func:`sonar_echoes` casts them with :func:`~parcover_env.geometry.ray_kernels.segment_fan_spans` (the same
hits; cheaper for a wide fan among many walls), else with :func:`~parcover_env.geometry.ray_kernels.segment_fan`
(a ring's few beams, or a few walls)."""
FAN_SPANS_WALLS = 16
"""See :data:`FAN_SPANS_MIN` (the two casts cost the same at about 16 walls around a 144-ray fan)."""
_DISC_SLACK = 1e-6
"""Margin (m) of the disc range cull of :func:`sonar_echoes`: rounding never culls a disc a sub-ray hits."""
@njit(cache=True, inline="always")
def _near_discs(x0, y0, cx, cy, r2, mine, rmax, terms):
    """The discs ``cx, cy`` (squared radii ``r2``) but ``mine`` that a ray from ``(x0, y0)`` can hit
    within ``rmax`` (the nearest point ``|oc| - r`` within it, or the origin inside), compacted into
    the first ``m`` entries of ``terms`` (``m`` returned): the terms ``oc = o - c`` and
    ``|oc|^2 - r^2`` of :func:`disc_hit_from` and the discs themselves."""
    ocx, ocy, cc, kept_x, kept_y, kept_r2 = terms
    m = 0
    for d in range(cx.shape[0]):
        if d == mine:
            continue
        dx = x0 - cx[d]
        dy = y0 - cy[d]
        c = (dx * dx + dy * dy) - r2[d]
        if c > 0.0 and math.sqrt(dx * dx + dy * dy) - math.sqrt(r2[d]) > rmax + _DISC_SLACK:
            continue
        ocx[m] = dx
        ocy[m] = dy
        cc[m] = c
        kept_x[0, m] = cx[d]
        kept_y[0, m] = cy[d]
        kept_r2[m] = r2[d]
        m += 1
    return m


@njit(cache=True)
def _normals(segs):
    """``(S, 2)`` unit normals ``(-e_y, e_x) / |e|`` of the segments ``e = (x2 - x1, y2 - y1)``."""
    out = np.empty((segs.shape[0], 2))
    for i in range(segs.shape[0]):
        ex = segs[i, 2] - segs[i, 0]
        ey = segs[i, 3] - segs[i, 1]
        norm = math.sqrt(ex * ex + ey * ey)
        if norm > 0.0:  # (a degenerate segment is never hit: no normal needed)
            out[i, 0] = -ey / norm
            out[i, 1] = ex / norm
        else:
            out[i, 0] = out[i, 1] = 0.0
    return out


@njit(cache=True, inline="always")
def _second_leg(x0, y0, ddx, ddy, t1, i1, walls, normals, near, discs, rules, cull):
    """Echo length ``t1 + t2`` of a sub-ray from ``(x0, y0)`` mirrored at ``t1`` by segment ``i1`` (unit
    normals ``normals``), inf if its second leg finds no echoing surface within ``rmax - t1`` (walls
    ``near``; the :class:`Discs` ``discs``, one set (row 0), none skipped: the origin's discs within
    ``rmax``, :func:`_near_discs`, as a path of length <= ``rmax`` meets no other)."""
    segs, seg_len = walls.segments, walls.lengths
    rule = rules[0]
    rmax, cos_min, nudge, box_cull = rule.range_max, rule.cos_min, rule.nudge, rule.box_cull
    nx = normals[i1, 0]
    ny = normals[i1, 1]
    f = 2.0 * (ddx * nx + ddy * ny)
    d2x = ddx - f * nx
    d2y = ddy - f * ny
    px = (x0 + ddx * t1) + d2x * nudge
    py = (y0 + ddy * t1) + d2y * nudge
    reach = rmax - t1
    if cull.bound < rmax:  # walls only as far as the bound (and a margin): the echo, or one read above the bound
        reach = min(reach, (cull.bound - t1) + _LEG_MARGIN)
    if cull.boxed and box_cull and math.isfinite(reach):  # the near walls' boxes (near_boxes) culled in one pass
        t2w, i2, den2 = segment_hit_boxed(px, py, d2x, d2y, segs, near, cull.boxes, cull.meets, reach)
    else:
        t2w, i2, den2 = segment_hit(px, py, d2x, d2y, segs, near, reach, box_cull and math.isfinite(reach), False)
    if not (i2 >= 0 and t2w <= reach):
        t2w = np.inf
        i2 = -1
    wall2 = t2w if _incidence(den2, seg_len, i2) >= cos_min else np.inf
    td2 = disc_hit(px, py, d2x, d2y, discs.cx, discs.cy, 0, discs.r2, -1)
    t2 = (td2 if td2 < t2w else wall2) + nudge
    return t1 + t2 if t2 <= rmax - t1 else np.inf


@njit(cache=True, nogil=True)
def sonar_corner_echoes(ox, oy, axes, walls, idx, cnt, discs, rules, reading):
    """Lower ``reading (N, B)`` to the distance of every concave corner ``points (C, 2)`` (wall
    directions ``u1, u2``) of the :class:`WallSet` that origin ``n`` sees from inside the corner's
    wedge, within ``range_max``, with no wall (nor one of the :class:`Discs`) in between, and inside
    beam ``b``'s cone (``|bearing - axis| <= half_cone``); the concave-corner rule of
    :func:`parcover_env.sensors.sonar.simulate_beams`. Walls are looked up in the origin's list
    ``idx[n, :cnt[n]]`` of those within ``range_max`` (:func:`near_segments`), and so are the
    corners (those listed at these walls, ``owned``: a corner within range lies on a wall within
    it). A reading is the nearest qualifying corner whatever the order they come in."""
    segs, pts, u1, u2, owned = walls.segments, walls.points, walls.u1, walls.u2, walls.owned
    cx, cy, r2, owner = discs.cx, discs.cy, discs.r2, discs.owner
    rmax, half = rules[0].range_max, rules[0].half_cone
    has_discs = cx.shape[1] > 0
    per_origin = cx.shape[0] > 1
    n_beams = axes.shape[1]
    step = 2.0 * math.pi / n_beams if n_beams > 0 else 0.0
    span = int(math.floor((half + _FAN_MARGIN) / step)) + 1 if n_beams > 0 else 0
    boxes = np.empty((4, segs.shape[0]))  # per origin: the near walls' bounding boxes (the sight lines' culls)
    meets = np.empty(segs.shape[0], dtype=np.bool_)
    for n in range(ox.shape[0]):
        x0 = ox[n]
        y0 = oy[n]
        near = idx[n, :cnt[n]]
        boxed = False  # the boxes filled for this origin (at its first sight line)
        fan = 2 * span + 1 < n_beams and owned.shape[0] > 0 and even_fan(axes[n], step)
        for q in range(2 * near.shape[0]):
            c = owned[near[q // 2], q % 2]
            if c < 0:
                continue
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
            first, count = 0, n_beams
            if fan:  # an even fan: only the beams whose axis lies within the cone (and a margin) of the bearing
                rel = wrap(bearing - axes[n, 0])
                first = int(math.floor((rel - (half + _FAN_MARGIN)) / step))
                count = int(math.floor((rel + (half + _FAN_MARGIN)) / step)) - first + 1
            for k in range(count):
                b = (first + k) % n_beams
                if not (dist < reading[n, b] and in_cone(bearing - axes[n, b], half)):
                    continue
                if seen < 0:
                    dx = vx / dist
                    dy = vy / dist
                    if not boxed:
                        near_boxes(segs, near, boxes)
                        boxed = True
                    seen = 0 if wall_before_boxed(x0, y0, dx, dy, segs, near, boxes, meets,
                                                  dist * (1.0 - 1e-7) - 1e-9, dist) else 1
                    if seen and has_discs and not disc_hit(x0, y0, dx, dy, cx, cy, n if per_origin else 0, r2,
                                                            owner[n]) >= dist:
                        seen = 0  # a robot in between
                if seen:
                    reading[n, b] = dist


class CornerView(NamedTuple):
    """The concave corners one origin sees from inside their wedges within ``range_max`` (:func:`corner_view`),
    for the beams of any heading from there (:func:`origin_corners`)."""

    dist: np.ndarray
    """``(C,)`` distance (m), bearing (rad) and the vector to each corner (m), the first ``count[0]`` of them."""
    bearing: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    seen: np.ndarray
    """``(C,)`` int64 line of sight (1 clear, 0 blocked by a wall or robot, -1 not looked yet)."""
    count: np.ndarray
    """``(1,)`` int64: how many corners are listed."""


@njit(cache=True)
def corner_scratch(walls):
    """An empty :class:`CornerView` for the corners of the :class:`WallSet` ``walls``."""
    c = walls.points.shape[0]
    return CornerView(np.empty(c), np.empty(c), np.empty(c), np.empty(c), np.empty(c, dtype=np.int64),
                      np.zeros(1, dtype=np.int64))


@njit(cache=True, nogil=True)
def corner_view(x0, y0, walls, near, rules, view):
    """Fill the :class:`CornerView` ``view`` for the origin ``(x0, y0)`` with the near walls ``near``: the corners
    listed at them (``owned``), within ``range_max`` and seen from inside their wedge, in that order, their
    lines of sight not looked at yet."""
    pts, u1, u2, owned = walls.points, walls.u1, walls.u2, walls.owned
    rmax = rules[0].range_max
    k = 0
    for q in range(2 * near.shape[0]):
        c = owned[near[q // 2], q % 2]
        if c < 0:
            continue
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
        view.dist[k] = dist
        view.bearing[k] = math.atan2(vy, vx)
        view.vx[k] = vx
        view.vy[k] = vy
        view.seen[k] = -1
        k += 1
    view.count[0] = k


@njit(cache=True, nogil=True)
def origin_corners(x0, y0, axes, walls, near, seen, rules, reading, wb, boxed, view):
    """:func:`sonar_corner_echoes` of one origin ``(x0, y0)`` whose corners :func:`corner_view` listed in ``view``
    (their lines of sight kept there, for other headings from the same origin): lower its readings
    ``reading (B,)`` of the beams ``axes (B,)``, the walls ``near`` (their boxes in the :class:`WallBoxes` ``wb``
    if ``boxed``, else filled at the first sight line) and the discs it sees (a :class:`DiscRow` ``seen``)."""
    segs = walls.segments
    boxes, meets = wb.boxes, wb.meets
    half = rules[0].half_cone
    has_discs = seen.cx.shape[1] > 0
    n_beams = axes.shape[0]
    step = 2.0 * math.pi / n_beams if n_beams > 0 else 0.0
    span = int(math.floor((half + _FAN_MARGIN) / step)) + 1 if n_beams > 0 else 0
    fan = view.count[0] > 0 and 2 * span + 1 < n_beams and even_fan(axes, step)
    for c in range(view.count[0]):
        dist = view.dist[c]
        bearing = view.bearing[c]
        first, count = 0, n_beams
        if fan:  # an even fan: only the beams whose axis lies within the cone (and a margin) of the bearing
            rel = wrap(bearing - axes[0])
            first = int(math.floor((rel - (half + _FAN_MARGIN)) / step))
            count = int(math.floor((rel + (half + _FAN_MARGIN)) / step)) - first + 1
        for k in range(count):
            b = (first + k) % n_beams
            if not (dist < reading[b] and in_cone(bearing - axes[b], half)):
                continue
            if view.seen[c] < 0:  # line of sight: looked at when a beam's cone first holds the corner
                dx = view.vx[c] / dist
                dy = view.vy[c] / dist
                if not boxed:
                    near_boxes(segs, near, boxes)
                    boxed = True
                clear = 0 if wall_before_boxed(x0, y0, dx, dy, segs, near, boxes, meets,
                                               dist * (1.0 - 1e-7) - 1e-9, dist) else 1
                if clear and has_discs and not disc_hit(x0, y0, dx, dy, seen.cx, seen.cy, seen.row, seen.r2,
                                                        seen.mine) >= dist:
                    clear = 0  # a robot in between
                view.seen[c] = clear
            if view.seen[c]:
                reading[b] = dist


_FAN_MARGIN = 1e-6
"""Margin (rad) by which :func:`sonar_corner_echoes` widens a cone when it picks the beams of an even
fan that may hold a corner (far above the rounding of the axes, ~1e-15 rad)."""


@njit(cache=True, inline="always")
def even_fan(axes, step):
    """Whether the beam axes ``axes (B,)`` (rad) lie ``step`` apart in order, ``axes[b] = axes[0] + b
    step`` within 1e-9 rad, unwrapped (a 360-degree scan at any heading), so that the beams within an angle of
    a bearing follow from its offset to ``axes[0]``."""
    even = True
    b = 1
    while even and b < axes.shape[0]:
        even = abs((axes[b] - axes[0]) - b * step) <= 1e-9
        b += 1
    return even


@njit(cache=True, nogil=True)
def beam_readings(ox, oy, axes, offsets, share, walls, discs, rules, reading):
    """Noise-free echoes ``reading (N, B)`` (inf: none) of beams ``axes (N, B)`` from origins ``ox, oy``
    (:func:`parcover_env.sensors.sonar.simulate_beams`): the near-wall lists within ``range_max``
    (plus ``near_slack``), :func:`sonar_echoes`, then the concave corners
    (:func:`sonar_corner_echoes`) if specular, in one call."""
    rule = rules[0]
    segs = walls.segments
    n = ox.shape[0]
    idx = np.empty((n, segs.shape[0]), dtype=np.int64)
    cnt = np.empty(n, dtype=np.int64)
    near_segments(ox, oy, segs, rule.range_max + rule.near_slack, idx, cnt)
    sonar_echoes(ox, oy, axes, offsets, share, walls, idx, cnt, discs, rules, reading)
    if rule.specular and walls.points.shape[0] > 0:
        sonar_corner_echoes(ox, oy, axes, walls, idx, cnt, discs, rules, reading)




class PoseScratch(NamedTuple):
    """Scratch of :func:`pose_readings` for one pose after another (allocated once: e.g. a polish's every
    step)."""

    idx: np.ndarray
    """``(1, S)`` int64 and ``(1,)``: the pose's near-wall list (:func:`near_segments`)."""
    cnt: np.ndarray
    echoes: EchoScratch
    seen: CornerView
    mirror: np.ndarray
    """``(B,)`` scratch of :func:`origin_first_legs`."""


@njit(cache=True)
def pose_scratch(offsets, share, walls, n_discs):
    """The :class:`PoseScratch` of beams shared as ``share (B, J)`` among ``walls`` and ``n_discs`` discs."""
    segs = walls.segments
    return PoseScratch(np.empty((1, segs.shape[0]), dtype=np.int64), np.empty(1, dtype=np.int64),
                       echo_scratch(offsets, share, segs, n_discs), corner_scratch(walls), np.empty(share.shape[0]))


@njit(cache=True, nogil=True)
def pose_readings(x0, y0, axes, share, walls, discs, rules, reading, ps):
    """:func:`beam_readings` of one origin ``(x0, y0)`` (``axes (B,)``, discs row 0, none of them its own) into
    ``reading (B,)``, the same numbers, with the :class:`PoseScratch` ``ps`` (no allocation)."""
    rule = rules[0]
    segs = walls.segments
    ox = np.full(1, x0)
    oy = np.full(1, y0)
    near_segments(ox, oy, segs, rule.range_max + rule.near_slack, ps.idx, ps.cnt)
    near = ps.idx[0, :ps.cnt[0]]
    cx, cy, r2, owner = discs.cx, discs.cy, discs.r2, discs.owner
    seen = DiscRow(cx, cy, 0, r2, owner[0])
    m = origin_first_legs(x0, y0, axes, share, walls, near, seen, rules, ps.echoes, reading, ps.mirror)
    origin_second_legs(x0, y0, share, walls, near, m, owner, rules, ps.echoes, reading, ps.mirror)
    if rule.specular and walls.points.shape[0] > 0:
        corner_view(x0, y0, walls, near, rules, ps.seen)
        origin_corners(x0, y0, axes, walls, near, seen, rules, reading, WallBoxes(ps.echoes.boxes, ps.echoes.meets),
                       ps.echoes.fdx.shape[0] >= FAN_SPANS_MIN, ps.seen)
