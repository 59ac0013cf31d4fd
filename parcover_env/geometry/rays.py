"""The one ray-casting kernel: batched rays against wall segments and robot discs.

Every sensor casts through here: sonar beams and their cone sub-rays, synthetic scans of the
localizer, visibility of map corners (sectors), the Kinect's static scene, the follower camera's
line of sight.

Conventions: points are ``(..., 2)`` float arrays in metres; a segment array is ``(S, 4)`` with
rows ``(x1, y1, x2, y2)``; angles are radians, counter-clockwise from +x.

Ray layouts. ``origins (R, 2)`` with ``directions (R, 2)``: one ray per origin. ``origins (N, 2)``
with ``directions (N, M, 2)``: a *fan* of ``M`` rays from each origin (all beams of all robots in
one call). Fans are range-culled when it pays: each origin's rays are tested only against the
segments (discs) within ``max_range`` of it. A hit at ``t`` lies within ``t`` of its origin, so
every hit up to ``max_range`` is found exactly as by the full test. Culling: each ray is tested only
against the segments whose bounding box meets the box of its reach ``[o, o + max_range d]`` (single
rays too); discs of a fan only when within ``max_range`` of the origin. Culled and full tests give
the same numbers bit for bit (same arithmetic per pair, same tie-breaking).

A hit farther than ``max_range`` is reported as no hit: distance ``inf``, segment index ``-1``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["RayHits", "polygon_edges", "cast_rays", "cast_rays_discs", "segments_blocked",
           "point_segment_distance"]

_EPS = 1e-12
"""Parallel rays (|direction x segment| below this) never hit; segment ends get this slack."""
CULL_MIN_RAYS = 32
"""Rays per origin from which a fan is range-culled ...               (performance, not physics)"""
CULL_MIN_WORK = 50_000
"""... when rays x segments (or discs) reach this: below, culling costs more than it saves."""
CULL_MIN_PAIRS = 10_000
"""Single rays (one per origin) are box-culled from this many rays x segments on."""


@dataclass(frozen=True, eq=False)
class RayHits:
    """First hit per ray, shaped like ``directions[..., 0]``."""

    distance: np.ndarray
    """Distance along the (unit) direction to the first hit; ``inf`` if none within range (m)."""
    index: np.ndarray
    """Index of the segment hit, ``-1`` if none."""
    cos_incidence: np.ndarray | None = None
    """``|cos|`` of the angle between the ray and the hit segment's normal (1 = head-on), 0 where
    nothing is hit; only when asked (``with_cos=True``) and for unit directions."""


def polygon_edges(coords) -> np.ndarray:
    """Edges ``(N, 4)`` of a closed ring given as ``(N, 2)`` or ``(N+1, 2)`` (closed) vertices."""
    pts = np.asarray(coords, dtype=float)
    if len(pts) > 1 and np.allclose(pts[0], pts[-1]):
        pts = pts[:-1]
    return np.concatenate([pts, np.roll(pts, -1, axis=0)], axis=1)


def _pays(n_origins: int, per_origin: int, n_targets: int, max_range: float) -> bool:
    return (math.isfinite(max_range) and per_origin >= CULL_MIN_RAYS
            and n_origins * per_origin * n_targets >= CULL_MIN_WORK)


def _t_plane(ox, oy, dx, dy, seg):
    """Ray parameter ``t`` of every (ray, segment) pair (inf where the ray misses) and ``den``.

    Solves ``o + t d = a + u e``: ``t = (w x e) / (d x e)``, ``u = (w x d) / (d x e)`` with
    ``w = a - o``. Works on one contiguous plane per coordinate (no ``(..., 2)`` temporaries)."""
    ax, ay = seg[..., 0], seg[..., 1]
    ex, ey = seg[..., 2] - ax, seg[..., 3] - ay
    den = dx * ey - dy * ex
    wx, wy = ax - ox, ay - oy
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / den
        u = (wx * dy - wy * dx) / den
    ok = (t >= 0.0) & (u >= -_EPS) & (u <= 1.0 + _EPS) & (np.abs(den) > _EPS)
    return np.where(ok, t, np.inf), den, ex, ey


def _first(t, den, ex, ey, axis_len, with_cos):
    """Nearest hit along the last axis: ``(t, position along that axis, |cos| or None)``."""
    j = np.argmin(t, axis=-1)[..., None]
    tmin = np.take_along_axis(t, j, axis=-1)[..., 0]
    if not with_cos:
        return tmin, j[..., 0], None
    elen = np.broadcast_to(np.hypot(ex, ey), t.shape)
    cos = (np.abs(np.take_along_axis(den, j, axis=-1))
           / np.maximum(np.take_along_axis(elen, j, axis=-1), 1e-9))[..., 0]  # |d x e| / |e|
    return tmin, j[..., 0], cos


def cast_rays(origins, directions, segments, max_range: float = math.inf, *,
              with_cos: bool = False, cull: bool | None = None) -> RayHits:
    """First hit of each ray on ``segments`` within ``max_range`` (see the module docstring for the
    ray layouts). ``cull``: force (True) or forbid (False) range culling of fans; None decides by
    size. Directions need not be unit (distances are then in units of their length), except for
    ``cos_incidence``."""
    origins = np.asarray(origins, dtype=float)
    directions = np.asarray(directions, dtype=float)
    segments = np.asarray(segments, dtype=float).reshape(-1, 4)
    shape = directions.shape[:-1]
    fan = directions.ndim == 3
    if directions.size == 0 or len(segments) == 0:
        return RayHits(np.full(shape, np.inf), np.full(shape, -1, dtype=np.int64),
                       np.zeros(shape) if with_cos else None)
    if fan:
        n, m = shape
        if cull is None:
            cull = _pays(n, m, len(segments), max_range)
        if cull and math.isfinite(max_range):
            t, idx, cos = _rays_culled(np.repeat(origins, m, axis=0), directions.reshape(n * m, 2), segments,
                                       max_range, with_cos)
            t, idx = t.reshape(n, m), idx.reshape(n, m)
            cos = cos.reshape(n, m) if with_cos else None
        else:
            t, den, ex, ey = _t_plane(origins[:, None, 0:1], origins[:, None, 1:2],
                                      directions[..., 0:1], directions[..., 1:2], segments[None, None])
            t, idx, cos = _first(t, den, ex, ey, len(segments), with_cos)
    else:
        if cull is None:
            cull = math.isfinite(max_range) and len(origins) * len(segments) >= CULL_MIN_PAIRS
        if cull and math.isfinite(max_range):
            t, idx, cos = _rays_culled(origins, directions, segments, max_range, with_cos)
        else:
            t, den, ex, ey = _t_plane(origins[:, 0:1], origins[:, 1:2], directions[:, 0:1], directions[:, 1:2],
                                      segments[None])
            t, idx, cos = _first(t, den, ex, ey, len(segments), with_cos)
    hit = np.isfinite(t) & (t <= max_range)
    return RayHits(np.where(hit, t, np.inf), np.where(hit, idx, -1),
                   np.where(hit, cos, 0.0) if with_cos else None)


_BOX_SLACK = 1e-9
"""Margin (m) of the bounding boxes of the box-culled single rays: rounding never drops a hit."""


def _box_pairs(ox, oy, dx, dy, reach, segments) -> tuple[np.ndarray, np.ndarray]:
    """(ray, segment) index pairs whose bounding boxes meet: the ray's ``[o, o + reach d]`` and the
    segment's, each grown by ``_BOX_SLACK``; sorted by ray, then by segment index."""
    fx, fy = ox + dx * reach, oy + dy * reach
    rx0, rx1 = np.minimum(ox, fx) - _BOX_SLACK, np.maximum(ox, fx) + _BOX_SLACK
    ry0, ry1 = np.minimum(oy, fy) - _BOX_SLACK, np.maximum(oy, fy) + _BOX_SLACK
    sx0, sx1 = np.minimum(segments[:, 0], segments[:, 2]), np.maximum(segments[:, 0], segments[:, 2])
    sy0, sy1 = np.minimum(segments[:, 1], segments[:, 3]), np.maximum(segments[:, 1], segments[:, 3])
    near = ((sx0[None, :] <= rx1[:, None]) & (sx1[None, :] >= rx0[:, None])
            & (sy0[None, :] <= ry1[:, None]) & (sy1[None, :] >= ry0[:, None]))
    return np.nonzero(near)


def _rays_culled(origins, dirs, segments, reach, with_cos):
    """Single rays ``(R, 2)`` tested only against the segments whose bounding box meets the box of
    the ray's reach ``[o, o + reach d]``: the (ray, segment) pairs are computed flat, each with the
    same arithmetic as the full test, and the nearest hit per ray is the lowest-index one among equal
    distances (as ``argmin``), so the result is the full test's, bit for bit."""
    r = len(origins)
    ox, oy, dx, dy = origins[:, 0], origins[:, 1], dirs[:, 0], dirs[:, 1]
    ri, si = _box_pairs(ox, oy, dx, dy, reach, segments)
    tmin = np.full(r, np.inf)
    idx = np.zeros(r, dtype=np.int64)
    cos = np.zeros(r) if with_cos else None
    if len(ri) == 0:
        return tmin, idx, cos
    t, den, ex, ey = _t_plane(ox[ri], oy[ri], dx[ri], dy[ri], segments[si])
    starts = np.flatnonzero(np.concatenate([[True], ri[1:] != ri[:-1]]))
    tmin[ri[starts]] = np.minimum.reduceat(t, starts)
    at_min = np.flatnonzero((t == tmin[ri]) & np.isfinite(t))
    ray_at_min = ri[at_min]
    first = at_min[np.concatenate([[True], ray_at_min[1:] != ray_at_min[:-1]])] if len(at_min) else at_min
    idx[ri[first]] = si[first]
    if with_cos:
        cos[ri[first]] = np.abs(den[first]) / np.maximum(np.hypot(ex[first], ey[first]), 1e-9)
    return tmin, idx, cos


def segments_blocked(a, b, segments) -> np.ndarray:
    """Whether the open segment ``a -> b`` crosses any of ``segments``, per row of ``a, b (R, 2)``."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    segments = np.asarray(segments, dtype=float).reshape(-1, 4)
    if len(a) == 0 or len(segments) == 0:
        return np.zeros(len(a), dtype=bool)
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    if len(a) * len(segments) < CULL_MIN_PAIRS:
        t, _, _, _ = _t_plane(a[:, 0:1], a[:, 1:2], dx[:, None], dy[:, None], segments[None])
        return ((t > 0.0) & (t < 1.0)).any(axis=1)
    # box-culled: a crossing lies inside both bounding boxes (same test per pair as above)
    ri, si = _box_pairs(a[:, 0], a[:, 1], dx, dy, 1.0, segments)
    t, _, _, _ = _t_plane(a[ri, 0], a[ri, 1], dx[ri], dy[ri], segments[si])
    out = np.zeros(len(a), dtype=bool)
    out[ri[(t > 0.0) & (t < 1.0)]] = True
    return out


def _disc_t(ocx, ocy, dx, dy, c):
    b = ocx * dx + ocy * dy
    disc = b * b - c
    t_near = -b - np.sqrt(np.maximum(disc, 0.0))
    ok = (disc >= 0.0) & ((c <= 0.0) | (t_near >= 0.0))
    return np.where(ok, np.where(c <= 0.0, 0.0, t_near), np.inf)  # origin inside a disc: t = 0


def cast_rays_discs(origins, directions, centres, radii, owner=None, max_range: float = math.inf, *,
                    cull: bool | None = None) -> np.ndarray:
    """Distance to the first disc hit per ray (``inf`` if none within ``max_range``), shaped like
    ``directions[..., 0]`` (same layouts as :func:`cast_rays`). ``centres``: ``(D, 2)`` discs seen
    by every origin, or ``(N, D, 2)`` a disc set per origin (batched worlds: each origin sees the
    robots of its own world; ``radii`` is then one radius for all). ``owner``: per origin, the index
    of a disc to ignore (the robot carrying the sensor) or -1. A ray starting inside another disc
    hits it at 0."""
    origins = np.asarray(origins, dtype=float)
    directions = np.asarray(directions, dtype=float)
    centres = np.asarray(centres, dtype=float)
    per_origin = centres.ndim == 3
    if not per_origin:
        centres = centres.reshape(-1, 2)
    shape = directions.shape[:-1]
    n_discs = centres.shape[-2]
    if directions.size == 0 or n_discs == 0:
        return np.full(shape, np.inf)
    rad = np.broadcast_to(np.asarray(radii, dtype=float), (n_discs,))
    r2 = rad * rad
    n = len(origins)
    owner = np.full(n, -1) if owner is None else np.asarray(owner)
    if per_origin:
        ocx = origins[:, 0:1] - centres[:, :, 0]  # (N, D)
        ocy = origins[:, 1:2] - centres[:, :, 1]
    else:
        ocx = origins[:, 0:1] - centres[None, :, 0]  # (N, D)
        ocy = origins[:, 1:2] - centres[None, :, 1]
    c = (ocx * ocx + ocy * ocy) - r2
    mine = np.arange(n_discs)[None, :] == owner[:, None]
    if directions.ndim == 3:
        m = shape[1]
        if cull is None:
            cull = _pays(n, m, n_discs, max_range)
        if cull and math.isfinite(max_range):
            near = (np.hypot(ocx, ocy) <= max_range + rad[None, :] + 1e-6) & ~mine
            width = int(near.sum(axis=1).max()) if n else 0
            if width == 0:
                return np.full(shape, np.inf)
            order = np.argsort(~near, axis=1, kind="stable")[:, :width]
            keep = np.take_along_axis(near, order, axis=1)[:, None, :]
            ocx, ocy, c = (np.take_along_axis(x, order, axis=1)[:, None, :] for x in (ocx, ocy, c))
            t = np.where(keep, _disc_t(ocx, ocy, directions[..., 0:1], directions[..., 1:2], c), np.inf)
        else:
            t = _disc_t(ocx[:, None], ocy[:, None], directions[..., 0:1], directions[..., 1:2], c[:, None])
            t = np.where(mine[:, None, :], np.inf, t)
    else:
        t = np.where(mine, np.inf, _disc_t(ocx, ocy, directions[:, 0:1], directions[:, 1:2], c))
    t = t.min(axis=-1)
    return np.where(t <= max_range, t, np.inf)


def point_segment_distance(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distances ``(P, S)`` from points ``(P, 2)`` to segments ``(S, 4)``."""
    p = np.asarray(points, dtype=float)[:, None, :]
    a = segments[None, :, 0:2]
    e = segments[None, :, 2:4] - a
    ee = np.maximum(np.einsum("psk,psk->ps", e, e), _EPS)
    u = np.clip(np.einsum("psk,psk->ps", p - a, e) / ee, 0.0, 1.0)
    closest = a + u[..., None] * e
    return np.linalg.norm(p - closest, axis=-1)
