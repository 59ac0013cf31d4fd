"""Exact visibility regions of map corners and their arrangement (Kim, Pearce & Amato §2.1-2.2).

A point ``q`` of the free space sees a corner ``c`` when the segment ``c q`` crosses no wall. The
walls hiding ``q`` from ``c`` are exactly the edges whose *shadow* from ``c`` contains ``q``: the
region behind the edge, bounded by the edge and the two rays from ``c`` through its end points.
So the visibility region of ``c`` is the free space minus the union of the shadows of all edges not
incident to ``c`` (shapely polygon booleans, no sampling), cut by the range disc when the sensor's
range is finite. The arrangement of all these regions over the free space is built by noding
their boundaries and polygonizing: every face sees one set of corners.

Floating point is the only approximation, with two documented tolerances:

* ``PRECISION``: the boundaries are noded with snap rounding (shapely ``union_all(grid_size=)``,
  GEOS OverlayNG) on a grid of this fraction of the map's diagonal, so two boundaries that
  coincide in exact arithmetic but were computed along different paths (a wall and a visibility
  edge running along it) become one line instead of a rounding sliver. Faces thinner than the grid
  vanish. The grid is relative, so counts do not change when the map is scaled, turned or moved.
* ``DISC_QUAD_SEGS``: a finite range disc is the inscribed polygon with ``4 * DISC_QUAD_SEGS``
  edges (shapely's ``buffer``); its radius is short by at most ``1 - cos(pi / (4 * 64))``, i.e.
  7.5e-5 of the range (0.19 mm at 2.54 m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

__all__ = ["PRECISION", "DISC_QUAD_SEGS", "Arrangement", "visibility_region", "visibility_arrangement"]

PRECISION = 1e-9
"""Snap-rounding grid of the arrangement, as a fraction of the map's diagonal."""
DISC_QUAD_SEGS = 64
"""Segments per quarter circle of a finite range disc."""


def _diagonal(map_model) -> float:
    x0, y0, x1, y1 = map_model.free.bounds
    return float(np.hypot(x1 - x0, y1 - y0))


def visibility_region(map_model, point, range_max: float = np.inf):
    """Region of ``map_model.free`` seen from ``point`` (a corner or any free point) within
    ``range_max``: the free space minus the shadows of every wall edge (see module docstring)."""
    p = np.asarray(point, dtype=float)
    segs = np.asarray(map_model.segments, dtype=float)
    diag = _diagonal(map_model)
    eps = 1e-12 * diag
    a, b = segs[:, :2] - p, segs[:, 2:] - p
    la, lb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    # edges at the point, or on a line through it, cast no shadow of positive area
    cast = (la > eps) & (lb > eps) & (np.abs(cross) > eps * (la + lb))
    far = 4.0 * diag
    a, b, la, lb = a[cast], b[cast], la[cast], lb[cast]
    quads = np.stack([a, b, b * (1.0 + far / lb)[:, None], a * (1.0 + far / la)[:, None]], axis=1) + p
    shadows = shapely.union_all(shapely.polygons(quads)) if len(quads) else shapely.Polygon()
    seen = map_model.free.difference(shadows)
    if np.isfinite(range_max):
        seen = seen.intersection(shapely.Point(p).buffer(range_max, quad_segs=DISC_QUAD_SEGS))
    # the region is star-shaped from the point: drop rounding crumbs that do not reach it
    parts = [g for g in getattr(seen, "geoms", [seen]) if g.geom_type == "Polygon" and not g.is_empty]
    near = [g for g in parts if g.distance(shapely.Point(p)) <= 1e-9 * diag]
    return shapely.union_all(near) if near else shapely.Polygon()


@dataclass(frozen=True, eq=False)
class Arrangement:
    """Faces of the free space cut by the boundaries of the visibility regions."""

    faces: list
    """One shapely Polygon per face."""
    visible: np.ndarray
    """``(n_faces, n_points)`` bool: whether each face lies in each point's visibility region."""
    shared: dict
    """``{(i, j): length}`` for faces ``i < j`` sharing boundary of positive length (m)."""


def _edge_keys(poly) -> list[tuple]:
    rings = [poly.exterior, *poly.interiors]
    keys = []
    for ring in rings:
        c = np.asarray(ring.coords)
        for u, v in zip(map(tuple, c[:-1]), map(tuple, c[1:]), strict=True):
            keys.append((min(u, v), max(u, v)))
    return keys


def _face_adjacency(faces: list) -> dict:
    """Shared boundary length per pair of faces; polygonized faces share exact vertex coordinates."""
    owner: dict = {}
    for i, f in enumerate(faces):
        for k in _edge_keys(f):
            owner.setdefault(k, []).append(i)
    shared: dict = {}
    for (u, v), ids in owner.items():
        ids = sorted(set(ids))
        length = float(np.hypot(v[0] - u[0], v[1] - u[1]))
        for x in range(len(ids)):
            for y in range(x + 1, len(ids)):
                shared[ids[x], ids[y]] = shared.get((ids[x], ids[y]), 0.0) + length
    return shared


def visibility_arrangement(map_model, points, range_max: float = np.inf) -> Arrangement:
    """The arrangement of the visibility regions of ``points (P, 2)`` over the free space."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    regions = [visibility_region(map_model, q, range_max) for q in pts]
    lines = [map_model.free.boundary] + [r.boundary for r in regions if not r.is_empty]
    # snap-rounding noding: boundaries equal in exact arithmetic become one line
    noded = shapely.union_all(lines, grid_size=PRECISION * _diagonal(map_model))
    cells = shapely.get_parts(shapely.polygonize(shapely.get_parts(noded)))
    faces = [c for c in cells if map_model.free.contains(c.representative_point())]
    shared = _face_adjacency(faces)
    visible = np.zeros((len(faces), len(pts)), dtype=bool)
    if faces:
        reps = np.array([f.representative_point().coords[0] for f in faces])
        for j, r in enumerate(regions):
            if not r.is_empty:
                visible[:, j] = shapely.contains_xy(r, reps[:, 0], reps[:, 1])
    return Arrangement(faces, visible, shared)
