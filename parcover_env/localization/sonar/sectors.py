"""Visibility sectors of a polygonal map for a range-limited sonar (Kim, Pearce & Amato §2.1-2.2).

Method (exact geometry, no sampling): the visibility region of every feature (concave corner, see
``features.py``) is a polygon, cut by the range disc when ``range_max`` is finite; their
arrangement over the free space is polygonized (``visibility.py``). Original sectors (rule 0) are
the maximal edge-connected unions of faces seeing the same set of features (faces that touch at a
point only are not adjacent). Sectors cover the free space; a region seeing no feature is a
sector with the empty set.

Relaxed sectors: rule #1 ("merge adjacent sectors which can see the same closest feature") merges
edge-adjacent original sectors whose closest feature is the same, the closest feature of a
sector being the one of its features nearest (Euclidean) to the sector's area centroid. Distances
within a relative ``TIE`` (1e-6) of the nearest tie (a centroid on a symmetry axis); a tied
sector takes the lowest-index tied feature that is the untied closest feature of an adjacent
sector, else its lowest-index tied feature. (With the lowest index alone, the T room of Fig. 3
gives 7 sectors, not 6.) Rule #2
("merge adjacent sectors which share some common visible feature") greedily merges adjacent
sectors while some feature stays visible from every original sector of the merged group (the pair
sharing most features first, then the larger pair, areas within ``TIE`` of the room's being equal,
then a fixed order of the pairs' feature sets). A merged sector stores the union of its
original sectors' features, as the paper does, and ``common``, the features seen from all of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from parcover_env.geometry import cast_rays
from parcover_env.localization.sonar.features import MapFeature, map_features
from parcover_env.localization.sonar.visibility import visibility_arrangement

__all__ = ["Sector", "compute_sectors", "visible_features", "sectors_summary", "RULE_NAMES"]

RULE_NAMES = {0: "original", 1: "rule #1", 2: "rule #2"}
TIE = 1e-6
"""Relative difference under which two distances (rule #1) or two areas (rule #2) are equal: far
above the arrangement's snap-rounding grid (``visibility.PRECISION``, 1e-9 of the diagonal)."""


@dataclass(frozen=True, eq=False)
class Sector:
    """A (relaxed) visibility sector: its region and the union of features seen from it."""

    polygon: shapely.Polygon | shapely.MultiPolygon
    features: frozenset[int]
    common: frozenset[int] = frozenset()
    """Features visible from every original sector merged into this one."""


def visible_features(points, map_model, features: list[MapFeature], range_max: float,
                     chunk: int = 4096) -> np.ndarray:
    """``(P, F)`` bool: feature in line of sight of each point and within ``range_max``."""
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    n_f = len(features)
    out = np.zeros((len(pts), n_f), dtype=bool)
    if n_f == 0 or len(pts) == 0:
        return out
    corners = np.stack([f.point for f in features])
    segs = map_model.segments
    for s in range(0, len(pts), chunk):
        p = pts[s:s + chunk]
        vec = corners[None, :, :] - p[:, None, :]
        dist = np.linalg.norm(vec, axis=-1)
        cand = (dist <= range_max) & (dist > 1e-9)
        pi, fi = np.nonzero(cand)
        if len(pi) == 0:
            continue
        d = vec[pi, fi] / dist[pi, fi, None]
        t = cast_rays(p[pi], d, segs).distance
        ok = t >= dist[pi, fi] * (1.0 - 1e-7) - 1e-9
        out[s + pi[ok], fi[ok]] = True
    return out


class _Groups:
    """Union-find over original sectors with per-group feature union / intersection and area."""

    def __init__(self, feats: list[frozenset[int]], areas: list[float]):
        self.parent = list(range(len(feats)))
        self.union = dict(enumerate(feats))
        self.common = dict(enumerate(feats))
        self.area = dict(enumerate(areas))

    def find(self, i: int) -> int:
        while self.parent[i] != i:
            self.parent[i] = self.parent[self.parent[i]]
            i = self.parent[i]
        return i

    def merge(self, a: int, b: int) -> None:
        a, b = self.find(a), self.find(b)
        if a == b:
            return
        if (self.area[a], -a) < (self.area[b], -b):
            a, b = b, a
        self.parent[b] = a
        self.union[a] = self.union[a] | self.union.pop(b)
        self.common[a] = self.common[a] & self.common.pop(b)
        self.area[a] += self.area.pop(b)


def _original_sectors(arr) -> tuple[list[list[int]], set[tuple[int, int]]]:
    """Faces grouped into original sectors (edge-connected, same visible set) and their adjacency."""
    n = len(arr.faces)
    parent = list(range(n))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    labels = [arr.visible[i].tobytes() for i in range(n)]
    for (i, j), length in arr.shared.items():
        if length > 0 and labels[i] == labels[j]:
            parent[find(i)] = find(j)
    roots = sorted({find(i) for i in range(n)})
    index = {r: k for k, r in enumerate(roots)}
    members = [[] for _ in roots]
    for i in range(n):
        members[index[find(i)]].append(i)
    adj = {tuple(sorted((index[find(i)], index[find(j)]))) for (i, j), length in arr.shared.items()
           if length > 0 and find(i) != find(j)}
    return members, adj


def compute_sectors(map_model, range_max: float, rule: int = 0,
                    features: list[MapFeature] | None = None) -> list[Sector]:
    """Sectors of ``map_model`` for a sonar of ``range_max`` (``inf`` = visibility only): rule 0
    original, 1 or 2 relaxed. Exact geometry (module docstring); sorted by decreasing area."""
    if rule not in (0, 1, 2):
        raise ValueError(f"rule must be 0 (original), 1 or 2, got {rule!r}")
    if not range_max > 0:
        raise ValueError(f"range_max must be > 0, got {range_max}")
    feats = map_features(map_model) if features is None else features
    points = np.array([f.point for f in feats], dtype=float).reshape(-1, 2)
    arr = visibility_arrangement(map_model, points, range_max)
    members, adj = _original_sectors(arr)
    face_area = np.array([f.area for f in arr.faces])
    face_centroid = np.array([f.centroid.coords[0] for f in arr.faces]).reshape(-1, 2)
    areas = [float(face_area[m].sum()) for m in members]
    centroids = np.array([face_area[m] @ face_centroid[m] / face_area[m].sum() for m in members]).reshape(-1, 2)
    sets = [frozenset(np.nonzero(arr.visible[m[0]])[0].tolist()) for m in members]
    groups = _Groups(sets, areas)
    if rule == 1:
        _merge_rule1(groups, adj, centroids, points)
    elif rule == 2:
        _merge_rule2(groups, adj, total_area=float(face_area.sum()))
    by_root: dict[int, list[int]] = {}
    for k, m in enumerate(members):
        by_root.setdefault(groups.find(k), []).extend(m)
    sectors = [Sector(shapely.union_all([arr.faces[i] for i in faces]), groups.union[r], groups.common[r])
               for r, faces in by_root.items()]
    return sorted(sectors, key=lambda s: -s.polygon.area)


def _closest(common: frozenset[int], centroid: np.ndarray, points: np.ndarray) -> list[int]:
    """Features of ``common`` nearest ``centroid``, ties within a relative ``TIE`` (sorted; [] if none)."""
    if not common:
        return []
    idx = np.array(sorted(common))
    d = np.linalg.norm(points[idx] - centroid, axis=1)
    return idx[d <= d.min() * (1.0 + TIE)].tolist()


def _merge_rule1(groups: _Groups, adj, centroids: np.ndarray, points: np.ndarray) -> None:
    near = [_closest(groups.common[k], centroids[k], points) for k in range(len(centroids))]
    untied = [c[0] if len(c) == 1 else -1 for c in near]
    closest = list(untied)
    for k, c in enumerate(near):
        if len(c) > 1:  # a tie (a symmetry axis): take a neighbour's untied closest feature if tied
            nbrs = {untied[b if a == k else a] for a, b in adj if k in (a, b)}
            shared = sorted(nbrs & set(c))
            closest[k] = shared[0] if shared else c[0]
    for a, b in sorted(adj):
        if closest[a] == closest[b]:
            groups.merge(a, b)


def _merge_rule2(groups: _Groups, adj, total_area: float) -> None:
    while True:
        cands = []
        for a, b in adj:
            ra, rb = groups.find(a), groups.find(b)
            shared = groups.common[ra] & groups.common[rb]
            if ra != rb and shared:
                cands.append((len(shared), groups.area[ra] + groups.area[rb], ra, rb))
        if not cands:
            return
        most = max(c[0] for c in cands)
        cands = [c for c in cands if c[0] == most]
        # areas equal up to TIE count as equal, whatever the map's scale; then a fixed order
        big = max(c[1] for c in cands) - TIE * total_area
        best = max((c for c in cands if c[1] >= big), key=lambda c: sorted(
            (tuple(sorted(groups.union[c[2]])), tuple(sorted(groups.union[c[3]])))))
        groups.merge(best[2], best[3])


def sectors_summary(map_model, range_max: float, rule: int, features: list[MapFeature] | None = None,
                    sectors: list[Sector] | None = None) -> dict:
    """JSON-ready description of the sectors of ``map_model`` (computed unless ``sectors`` given).

    ``range_max`` may be ``inf`` (unlimited range: the paper's Figs. 3-4 are about visibility only);
    it is reported as ``null`` then, since JSON has no infinity. Keys: ``rule``, ``rule_name``,
    ``range_max``, ``n_features``, ``n_sectors``, ``features`` (corner ``[x, y]`` per feature index) and
    ``sectors`` (per sector: ``features`` union, ``common`` features, ``area`` m^2, ``centroid``).
    """
    feats = map_features(map_model) if features is None else features
    if sectors is None:
        sectors = compute_sectors(map_model, range_max, rule=rule, features=feats)
    rows = []
    for sec in sectors:
        c = sec.polygon.centroid
        rows.append({"features": sorted(int(f) for f in sec.features),
                     "common": sorted(int(f) for f in sec.common),
                     "area": float(sec.polygon.area), "centroid": [float(c.x), float(c.y)]})
    return {"rule": int(rule), "rule_name": RULE_NAMES[int(rule)],
            "range_max": float(range_max) if np.isfinite(range_max) else None,
            "n_features": len(feats), "n_sectors": len(sectors),
            "features": [[float(f.point[0]), float(f.point[1])] for f in feats], "sectors": rows}
