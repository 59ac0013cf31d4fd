"""Batched ray casting against segments and discs, and point-segment distances.

Conventions: points are ``(..., 2)`` float arrays in metres; a segment array is ``(S, 4)`` with
rows ``(x1, y1, x2, y2)``; angles are radians, counter-clockwise from +x.
"""

from __future__ import annotations

import numpy as np

__all__ = ["polygon_edges", "cast_rays", "cast_rays_discs", "point_segment_distance"]

_EPS = 1e-12


def polygon_edges(coords) -> np.ndarray:
    """Edges ``(N, 4)`` of a closed ring given as ``(N, 2)`` or ``(N+1, 2)`` (closed) vertices."""
    pts = np.asarray(coords, dtype=float)
    if len(pts) > 1 and np.allclose(pts[0], pts[-1]):
        pts = pts[:-1]
    return np.concatenate([pts, np.roll(pts, -1, axis=0)], axis=1)


def cast_rays(origins: np.ndarray, directions: np.ndarray, segments: np.ndarray,
              max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """First hit of each ray on ``segments``.

    origins ``(R, 2)``, unit directions ``(R, 2)``, segments ``(S, 4)``.
    Returns ``(distance (R,), segment index (R,))``: ``max_range`` and ``-1`` where nothing is hit.
    """
    origins = np.asarray(origins, dtype=float)
    directions = np.asarray(directions, dtype=float)
    n_rays = len(origins)
    if n_rays == 0 or len(segments) == 0:
        return np.full(n_rays, float(max_range)), np.full(n_rays, -1, dtype=np.int64)
    segments = np.asarray(segments, dtype=float)
    # one contiguous (R, S) plane per coordinate (no (R, S, 2) temporaries)
    ax, ay = segments[:, 0], segments[:, 1]
    ex, ey = segments[:, 2] - ax, segments[:, 3] - ay
    dx, dy = directions[:, 0:1], directions[:, 1:2]
    wx, wy = ax - origins[:, 0:1], ay - origins[:, 1:2]
    # Solve origin + t d = a + u e  ->  t = cross(w, e) / cross(d, e), u = cross(w, d) / cross(d, e)
    den = dx * ey - dy * ex
    num_t = wx * ey - wy * ex
    num_u = wx * dy - wy * dx
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num_t / den
        u = num_u / den
    valid = (np.abs(den) > _EPS) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
    t = np.where(valid, t, np.inf)
    idx = np.argmin(t, axis=1)
    dist = t[np.arange(n_rays), idx]
    hit = dist <= max_range
    return np.where(hit, dist, float(max_range)), np.where(hit, idx, -1)


def cast_rays_discs(origins: np.ndarray, directions: np.ndarray, centers: np.ndarray,
                    radii, owner: np.ndarray | None, max_range: float) -> np.ndarray:
    """Distance from each ray origin to the first disc hit (``max_range`` if none).

    ``owner (R,)`` gives, per ray, the index of a disc to ignore (the robot carrying the sensor),
    or -1. Rays starting inside a disc other than their owner hit it at distance 0.
    """
    n_rays = len(origins)
    if n_rays == 0 or len(centers) == 0:
        return np.full(n_rays, float(max_range))
    radii = np.broadcast_to(np.asarray(radii, dtype=float), (len(centers),))
    oc = origins[:, None, :] - centers[None, :, :]
    b = np.einsum("rck,rk->rc", oc, directions)
    c = np.einsum("rck,rck->rc", oc, oc) - radii[None, :] ** 2
    disc = b * b - c
    with np.errstate(invalid="ignore"):
        sq = np.sqrt(np.maximum(disc, 0.0))
    t_near = -b - sq
    t = np.where(c <= 0.0, 0.0, t_near)  # origin inside the disc
    ok = (disc >= 0.0) & ((c <= 0.0) | (t_near >= 0.0))
    if owner is not None:
        ok &= np.arange(len(centers))[None, :] != np.asarray(owner)[:, None]
    t = np.where(ok, t, np.inf)
    return np.minimum(t.min(axis=1), float(max_range))


def point_segment_distance(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distances ``(P, S)`` from points ``(P, 2)`` to segments ``(S, 4)``."""
    p = np.asarray(points, dtype=float)[:, None, :]
    a = segments[None, :, 0:2]
    e = segments[None, :, 2:4] - a
    ee = np.maximum(np.einsum("psk,psk->ps", e, e), _EPS)
    u = np.clip(np.einsum("psk,psk->ps", p - a, e) / ee, 0.0, 1.0)
    closest = a + u[..., None] * e
    return np.linalg.norm(p - closest, axis=-1)
