"""Free-space shortest paths of a disc robot: the lower bound the roadmap's ``c_max`` sits above.

``c_max`` (:class:`~parcover_env.planning.plan.Plan`) is measured on the roadmap (the medial axis
of the free space eroded by the planner's clearance), which keeps to the middle of corridors and
rooms; no robot can be faster than the shortest path of its centre through the free space eroded
by its radius alone. That path is a taut string: straight segments between the start, the
reflex vertices of the eroded free space (the rounded corners of the inflated obstacles) and the
target, so a visibility graph over those points holds it (Lozano-Pérez & Wesley 1979).

Discretization: shapely draws each inflated corner's circular arc as ``quad_segs`` chords per
quarter circle with their ends on the arc, so the eroded region it builds contains the exact one
and the distances stay lower bounds. The drawn corner contains the circle of radius
``radius * cos(pi / (4 quad_segs))`` (0.12 % smaller at the default 16: 0.2 mm at 0.165 m), so
a distance is no shorter than the exact one for that smaller radius (an L corridor, by hand:
0.1 mm short at 16 chords, 3.1 cm at 1). Points (start, targets) closer than ``radius`` to an
obstacle are moved to the nearest point of the eroded region.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import shapely
from shapely.geometry import Point, Polygon
from shapely.geometry.polygon import orient
from shapely.ops import nearest_points

__all__ = ["FREE_QUAD_SEGS", "DiscPaths", "free_space_distances", "reflex_vertices"]

FREE_QUAD_SEGS = 16
"""Chords per quarter circle of an inflated corner (see the module docstring for the error)."""

_EPS = 1e-7
"""Segments are tested for visibility against the eroded region grown by this (m): a segment
along the boundary or through a tangent vertex must not fail on rounding."""


def _reflex(region) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reflex vertices ``(K, 2)`` of ``region`` and their ring neighbours before / after them."""
    out, before, after = [np.zeros((0, 2))], [np.zeros((0, 2))], [np.zeros((0, 2))]
    for poly in getattr(region, "geoms", [region]):
        poly = orient(poly, sign=1.0)  # exterior counter-clockwise, holes clockwise: inside on the left
        for ring in (poly.exterior, *poly.interiors):
            pts = np.asarray(ring.coords, dtype=float)[:-1]
            if len(pts) < 3:
                continue
            a, c = np.roll(pts, 1, axis=0), np.roll(pts, -1, axis=0)
            cross = (pts[:, 0] - a[:, 0]) * (c[:, 1] - pts[:, 1]) - (pts[:, 1] - a[:, 1]) * (c[:, 0] - pts[:, 0])
            keep = cross < -1e-12  # a right turn with the inside on the left: reflex
            out.append(pts[keep])
            before.append(a[keep])
            after.append(c[keep])
    return np.concatenate(out), np.concatenate(before), np.concatenate(after)


def reflex_vertices(region) -> np.ndarray:
    """``(K, 2)`` vertices of ``region`` (a shapely Polygon or MultiPolygon) where its interior
    angle exceeds 180 deg: the only points where a shortest path inside it can bend."""
    return _reflex(region)[0]


def _tangent(pts: np.ndarray, before: np.ndarray, after: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Whether the line from ``pts[i]`` to ``pts[j]`` leaves both ring neighbours of ``pts[i]`` on one
    side (a taut path can only bend at ``pts[i]`` along such a line); True where ``before`` is NaN."""
    d = pts[j] - pts[i]
    u, w = before[i] - pts[i], after[i] - pts[i]
    cu = d[:, 0] * u[:, 1] - d[:, 1] * u[:, 0]
    cw = d[:, 0] * w[:, 1] - d[:, 1] * w[:, 0]
    return ~(cu * cw < -1e-18)  # NaN compares False: free points (start, targets) pass


def _snap(region, p: np.ndarray) -> np.ndarray:
    """``p`` if ``region`` covers it, else the nearest point of ``region``."""
    pt = Point(*p)
    if region.covers(pt):
        return p
    return np.asarray(nearest_points(region, pt)[0].coords[0], dtype=float)


def free_space_distances(free: Polygon, start, targets, radius: float,
                         quad_segs: int = FREE_QUAD_SEGS) -> np.ndarray:
    """``(n,)`` length (m) of the shortest path of a disc of ``radius`` whose centre goes from
    ``start`` to each of ``targets (n, 2)`` without its disc leaving ``free`` (the map's free
    space, :attr:`~parcover_env.world.map_model.MapModel.free`); ``inf`` for a target in another
    component of the eroded free space."""
    if not (radius >= 0 and int(quad_segs) >= 1):
        raise ValueError(f"radius must be >= 0 and quad_segs >= 1, got {radius}, {quad_segs}")
    tg = np.asarray(targets, dtype=float).reshape(-1, 2)
    s = np.asarray(start, dtype=float).reshape(2)
    if not (np.all(np.isfinite(tg)) and np.all(np.isfinite(s))):
        raise ValueError("start and targets must be finite (x, y) points")
    region = free.buffer(-radius, quad_segs=int(quad_segs)) if radius > 0 else free
    if region.is_empty or len(tg) == 0:
        return np.full(len(tg), math.inf)
    bends, before, after = _reflex(region)
    ends = np.vstack([_snap(region, s)[None], [_snap(region, t) for t in tg]])
    pts = np.vstack([ends, bends])
    nan = np.full(ends.shape, np.nan)
    before, after = np.vstack([nan, before]), np.vstack([nan, after])
    i, j = np.triu_indices(len(pts), k=1)
    cand = _tangent(pts, before, after, i, j) & _tangent(pts, before, after, j, i)
    i, j = i[cand], j[cand]
    seen = region.buffer(_EPS)
    shapely.prepare(seen)
    ok = shapely.covers(seen, shapely.linestrings(np.stack([pts[i], pts[j]], axis=1)))
    graph = nx.Graph()
    graph.add_nodes_from(range(len(pts)))
    length = np.hypot(*(pts[i] - pts[j]).T)
    graph.add_weighted_edges_from(zip(i[ok].tolist(), j[ok].tolist(), length[ok].tolist()))
    dist = nx.single_source_dijkstra_path_length(graph, 0)
    return np.array([dist.get(k, math.inf) for k in range(1, 1 + len(tg))])


class DiscPaths:
    """Shortest paths of a disc of ``radius`` through ``free`` for many queries (a robot steering
    around corners): the eroded free space, its bends and the visibility edges among them are built
    once; each :meth:`path` adds only its two ends. The same taut-string construction as
    :func:`free_space_distances`."""

    def __init__(self, free: Polygon, radius: float, quad_segs: int = FREE_QUAD_SEGS):
        if not (radius >= 0 and int(quad_segs) >= 1):
            raise ValueError(f"radius must be >= 0 and quad_segs >= 1, got {radius}, {quad_segs}")
        self.radius = float(radius)
        self.region = free.buffer(-radius, quad_segs=int(quad_segs)) if radius > 0 else free
        self._seen = self.region.buffer(_EPS)
        shapely.prepare(self._seen)
        self._bends, self._before, self._after = _reflex(self.region)
        n = len(self._bends)
        i, j = np.triu_indices(n, k=1)
        b, bb, ba = self._bends, self._before, self._after
        cand = _tangent(b, bb, ba, i, j) & _tangent(b, bb, ba, j, i)
        i, j = i[cand], j[cand]
        ok = shapely.covers(self._seen, shapely.linestrings(np.stack([b[i], b[j]], axis=1))) if len(i) else i > 0
        self._graph = nx.Graph()
        self._graph.add_nodes_from(range(n))
        length = np.hypot(*(b[i] - b[j]).T)
        self._graph.add_weighted_edges_from(zip(i[ok].tolist(), j[ok].tolist(), length[ok].tolist()))

    def clear(self, a, b) -> bool:
        """Whether the disc's centre can go straight from ``a`` to ``b`` without the disc leaving the
        free space (the segment lies in the eroded region)."""
        a, b = np.asarray(a, dtype=float).reshape(2), np.asarray(b, dtype=float).reshape(2)
        return bool(shapely.covers(self._seen, shapely.linestrings(np.stack([a, b])[None])[0]))

    def path(self, start, target) -> np.ndarray | None:
        """``(K, 2)`` vertices of the shortest path of the disc's centre from ``start`` to ``target``
        (each first moved to the nearest point of the eroded region if it lies outside): the moved
        start, the bends, the moved target; None when they lie in different components of it."""
        if self.region.is_empty:
            return None
        ends = np.stack([_snap(self.region, np.asarray(start, dtype=float).reshape(2)),
                         _snap(self.region, np.asarray(target, dtype=float).reshape(2))])
        if self.clear(ends[0], ends[1]):
            return ends
        b = self._bends
        n = len(b)
        graph = self._graph.copy()
        s_node, t_node = n, n + 1
        graph.add_nodes_from((s_node, t_node))
        if n:
            nan = np.full((1, 2), np.nan)
            for node, end in ((s_node, ends[0]), (t_node, ends[1])):
                pts = np.vstack([end[None], b])
                k = np.arange(1, n + 1)
                z = np.zeros(n, dtype=int)
                cand = _tangent(pts, np.vstack([nan, self._before]), np.vstack([nan, self._after]), k, z)
                lines = shapely.linestrings(np.stack([np.repeat(end[None], n, axis=0), b], axis=1))
                ok = cand & shapely.covers(self._seen, lines)
                length = np.hypot(*(b - end).T)
                graph.add_weighted_edges_from((node, int(m), float(length[m])) for m in np.flatnonzero(ok))
        try:
            nodes = nx.dijkstra_path(graph, s_node, t_node, weight="weight")
        except nx.NetworkXNoPath:
            return None
        return np.vstack([ends[0], *(b[m] for m in nodes[1:-1]), ends[1]])
