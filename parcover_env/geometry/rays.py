"""The one ray-casting kernel: batched rays against wall segments and robot discs.

Every sensor casts through here: sonar beams and their cone sub-rays, synthetic scans of the
localizer, visibility of map corners (sectors), the Kinect's static scene, the follower camera's
line of sight.

Conventions: points are ``(..., 2)`` float arrays in metres; a segment array is ``(S, 4)`` with
rows ``(x1, y1, x2, y2)``; angles are radians, counter-clockwise from +x.

Ray layouts. ``origins (R, 2)`` with ``directions (R, 2)``: one ray per origin. ``origins (N, 2)``
with ``directions (N, M, 2)``: a *fan* of ``M`` rays from each origin (all beams of all robots in
one call).

Formulas, per (ray, segment) pair: the ray ``o + t d`` meets the segment ``a + u e`` at
``t = (w x e) / (d x e)``, ``u = (w x d) / (d x e)`` with ``w = a - o``; a hit needs ``t >= 0``,
``-eps <= u <= 1 + eps`` and ``|d x e| > eps``. The nearest hit wins, ties going to the lowest
segment index; ``|cos|`` of incidence is ``|d x e| / |e|``. Per (ray, disc) pair, with
``oc = o - c``: ``b = oc . d``, ``c' = |oc|^2 - r^2``; a hit needs ``b^2 - c' >= 0`` and lies at
``-b - sqrt(b^2 - c')`` if that is ``>= 0``, or at 0 when the ray starts inside (``c' <= 0``).

Culling: with a finite ``max_range``, a ray is tested only against the segments whose bounding box
meets the box of its reach ``[o, o + max_range d]`` (grown by 1e-9 m); a hit within range lies in
both boxes, so culled and full tests give the same numbers bit for bit. Casts whose paths from an
origin are at most ``L`` long (the sonar) look up the walls in the origin's list of segments within
``L`` (:func:`near_segments`), which changes no result either. The loops are compiled
with numba (:mod:`parcover_env.geometry.ray_kernels`, imported on the first cast).

A hit farther than ``max_range`` is reported as no hit: distance ``inf``, segment index ``-1``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["RayHits", "polygon_edges", "cast_rays", "cast_rays_discs", "segments_blocked", "sight_lines_blocked",
           "point_segment_distance"]

_EPS = 1e-12
"""Segment-end slack of :func:`point_segment_distance` (as in the ray kernels)."""
BOX_CULL = True
"""Default of ``cull``: box-cull the segments of rays with a finite range (never changes a result)."""


def kernels():
    """The compiled loops (numba is imported on the first cast, not with the package)."""
    from parcover_env.geometry import ray_kernels

    return ray_kernels


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


def _plane(a: np.ndarray, col: int) -> np.ndarray:
    return np.ascontiguousarray(a[..., col], dtype=np.float64).reshape(-1)


def ray_planes(origins, directions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Flat coordinate planes ``ox, oy (N,)``, ``dx, dy (R,)`` and rays per origin."""
    origins = origins.reshape(-1, 2)
    one = len(origins) == 1  # one origin: all rays share it
    per = directions.shape[1] if directions.ndim == 3 else (len(directions) if one else 1)
    if len(directions.reshape(-1, 2)) != len(origins) * per:
        raise ValueError(f"directions {directions.shape} do not match origins {origins.shape}")
    return _plane(origins, 0), _plane(origins, 1), _plane(directions, 0), _plane(directions, 1), per


def cast_rays(origins, directions, segments, max_range: float = math.inf, *,
              with_cos: bool = False, cull: bool | None = None) -> RayHits:
    """First hit of each ray on ``segments`` within ``max_range`` (see the module docstring for the
    ray layouts). ``cull``: box-cull (True, the default :data:`BOX_CULL`) or test every segment
    (False); the result is the same. Directions need not be unit (distances are then in units of
    their length), except for ``cos_incidence``."""
    origins = np.asarray(origins, dtype=float)
    directions = np.asarray(directions, dtype=float)
    segments = np.ascontiguousarray(np.asarray(segments, dtype=float).reshape(-1, 4))
    shape = directions.shape[:-1]
    if directions.size == 0 or len(segments) == 0:
        return RayHits(np.full(shape, np.inf), np.full(shape, -1, dtype=np.int64),
                       np.zeros(shape) if with_cos else None)
    ox, oy, dx, dy, per = ray_planes(origins, directions)
    seg_len = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    t = np.empty(len(dx))
    idx = np.empty(len(dx), dtype=np.int64)
    cos = np.empty(len(dx))
    kernels().first_segment_hits(ox, oy, dx, dy, per, segments, seg_len, float(max_range),
                                  BOX_CULL if cull is None else bool(cull), t, idx, cos)
    return RayHits(t.reshape(shape), idx.reshape(shape), cos.reshape(shape) if with_cos else None)


def segments_blocked(a, b, segments) -> np.ndarray:
    """Whether the open segment ``a -> b`` crosses any of ``segments``, per row of ``a, b (R, 2)``:
    the ray ``a + t (b - a)`` meets one at ``0 < t < 1`` (formulas of the module docstring)."""
    a = np.asarray(a, dtype=float).reshape(-1, 2)
    b = np.asarray(b, dtype=float).reshape(-1, 2)
    segments = np.ascontiguousarray(np.asarray(segments, dtype=float).reshape(-1, 4))
    out = np.zeros(len(a), dtype=bool)
    if len(a) == 0 or len(segments) == 0:
        return out
    kernels().open_segments_blocked(_plane(a, 0), _plane(a, 1), _plane(b, 0), _plane(b, 1), segments, out)
    return out


def sight_lines_blocked(px: np.ndarray, py: np.ndarray, target: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Per point ``i`` of ``px, py (P,)``: whether the open segment to point ``target[i]`` crosses any
    of ``segments (S, 4)`` (:func:`segments_blocked` of that pair, the same floats); False where
    ``target[i] < 0``. ``px, py`` float64, ``target`` int64, ``segments`` float64, all C-contiguous."""
    out = np.empty(len(px), dtype=bool)
    kernels().sight_lines_blocked(px, py, target, segments, out)
    return out


NEAR_SLACK = 1e-6
"""Margin (m) of :func:`near_segments`: a hit point lies up to the kernels' segment-end slack and
the sonar's restart nudge (1e-7 m) beyond a path's length; this margin covers both."""


def near_segments(ox: np.ndarray, oy: np.ndarray, segments: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Per origin ``(ox[o], oy[o])``, the indices of the ``segments (S, 4)`` (C-contiguous) within
    ``reach`` (+ :data:`NEAR_SLACK`) by point-to-segment distance: ``idx[o, :cnt[o]]``, ascending."""
    idx = np.empty((len(ox), len(segments)), dtype=np.int64)
    cnt = np.empty(len(ox), dtype=np.int64)
    kernels().near_segments(ox, oy, segments, float(reach) + NEAR_SLACK, idx, cnt)
    return idx, cnt


def disc_planes(centres, radii, owner, n_origins: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Disc arguments of the compiled kernels: centre planes ``cx, cy (C, D)`` (``C = 1``: one disc
    set for all origins, else one row per origin), squared radii ``(D,)`` and ``owner (N,)``."""
    centres = np.asarray(centres, dtype=float)
    if centres.ndim != 3:
        centres = centres.reshape(1, -1, 2)
    elif centres.shape[0] == 1 and n_origins > 1:
        centres = np.broadcast_to(centres, (n_origins,) + centres.shape[1:])
    if np.ndim(radii) == 0:  # one radius for all discs (the common case, without broadcasting)
        r2 = np.full(centres.shape[1], float(radii) * float(radii))
    else:
        rad = np.broadcast_to(np.asarray(radii, dtype=float), (centres.shape[1],))
        r2 = np.ascontiguousarray(rad * rad)
    if owner is None:
        owner = np.full(n_origins, -1, dtype=np.int64)
    elif not (type(owner) is np.ndarray and owner.dtype == np.int64 and owner.shape == (n_origins,)
              and owner.flags.c_contiguous):
        owner = np.ascontiguousarray(np.broadcast_to(np.asarray(owner, dtype=np.int64), (n_origins,)))
    return np.ascontiguousarray(centres[..., 0]), np.ascontiguousarray(centres[..., 1]), r2, owner


def cast_rays_discs(origins, directions, centres, radii, owner=None, max_range: float = math.inf, *,
                    cull: bool | None = None) -> np.ndarray:
    """Distance to the first disc hit per ray (``inf`` if none within ``max_range``), shaped like
    ``directions[..., 0]`` (same layouts as :func:`cast_rays`). ``centres``: ``(D, 2)`` discs seen
    by every origin, or ``(N, D, 2)`` a disc set per origin (batched worlds: each origin sees the
    robots of its own world; ``radii`` is then one radius for all). ``owner``: per origin, the index
    of a disc to ignore (the robot carrying the sensor) or -1. A ray starting inside another disc
    hits it at 0. ``cull`` is accepted for symmetry with :func:`cast_rays` (discs are few: every
    disc is tested)."""
    del cull
    origins = np.asarray(origins, dtype=float)
    directions = np.asarray(directions, dtype=float)
    shape = directions.shape[:-1]
    if directions.size == 0 or np.shape(centres)[-2] == 0:
        return np.full(shape, np.inf)
    ox, oy, dx, dy, per = ray_planes(origins, directions)
    cx, cy, r2, owner = disc_planes(centres, radii, owner, len(ox))
    t = np.empty(len(dx))
    kernels().first_disc_hits(ox, oy, dx, dy, per, cx, cy, r2, owner, float(max_range), t)
    return t.reshape(shape)


def point_segment_distance(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distances ``(P, S)`` from points ``(P, 2)`` to segments ``(S, 4)``."""
    p = np.asarray(points, dtype=float)[:, None, :]
    a = segments[None, :, 0:2]
    e = segments[None, :, 2:4] - a
    ee = np.maximum(np.einsum("psk,psk->ps", e, e), _EPS)
    u = np.clip(np.einsum("psk,psk->ps", p - a, e) / ee, 0.0, 1.0)
    closest = a + u[..., None] * e
    return np.linalg.norm(p - closest, axis=-1)
