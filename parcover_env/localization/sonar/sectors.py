"""Visibility sectors of a polygonal map for a range-limited sonar (seed B §2.1-2.2).

Method (grid sampling, documented choice): the bounding box of the free space is cut into square
cells of ``resolution``; at each cell centre inside free space we compute which features (concave
corners) are visible — in line of sight and within ``range_max``. Original sectors (rule 0) are the
4-connected components of cells with the same visible set (components under ``min_cells`` cells,
discretization slivers along visibility lines, join their neighbour sharing most features). Cells
whose centre is outside free space take the label of the nearest inside cell, and every sector
polygon is the union of its cells clipped to the free space, so the sectors cover the free space.

Relaxed sectors: rule 1 merges adjacent sectors with the same closest visible feature (measured
from the sector's cell centroid); rule 2 greedily merges adjacent sectors while some feature stays
visible from every original sector of the merged group (the pair sharing most features first). A
merged sector stores the union of its original sectors' features, as the paper does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from scipy import ndimage

from parcover_env.geometry import cast_rays
from parcover_env.localization.sonar.features import MapFeature, map_features

__all__ = ["Sector", "compute_sectors", "visible_features", "sectors_summary", "RULE_NAMES"]

RULE_NAMES = {0: "original", 1: "rule #1", 2: "rule #2"}


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


def _components(sig_grid: np.ndarray) -> tuple[np.ndarray, int]:
    labels = np.full(sig_grid.shape, -1, dtype=np.int64)
    count = 0
    for s in np.unique(sig_grid[sig_grid >= 0]):
        lab, n = ndimage.label(sig_grid == s)
        mask = lab > 0
        labels[mask] = lab[mask] - 1 + count
        count += n
    return labels, count


def _adjacency(labels: np.ndarray) -> set[tuple[int, int]]:
    pairs = set()
    for a, b in ((labels[:, :-1], labels[:, 1:]), (labels[:-1, :], labels[1:, :])):
        m = (a >= 0) & (b >= 0) & (a != b)
        for x, y in zip(a[m].tolist(), b[m].tolist(), strict=True):
            pairs.add((min(x, y), max(x, y)))
    return pairs


class _Groups:
    """Union-find over original sectors with per-group feature union / intersection."""

    def __init__(self, feats: list[frozenset[int]], sizes: np.ndarray):
        self.parent = list(range(len(feats)))
        self.union = {i: f for i, f in enumerate(feats)}
        self.common = {i: f for i, f in enumerate(feats)}
        self.size = {i: int(s) for i, s in enumerate(sizes)}

    def find(self, i: int) -> int:
        while self.parent[i] != i:
            self.parent[i] = self.parent[self.parent[i]]
            i = self.parent[i]
        return i

    def merge(self, a: int, b: int) -> None:
        a, b = self.find(a), self.find(b)
        if a == b:
            return
        if self.size[a] < self.size[b]:
            a, b = b, a
        self.parent[b] = a
        self.union[a] = self.union[a] | self.union.pop(b)
        self.common[a] = self.common[a] & self.common.pop(b)
        self.size[a] += self.size.pop(b)


def compute_sectors(map_model, range_max: float, rule: int = 0, features: list[MapFeature] | None = None,
                    resolution: float = 0.05, min_cells: int = 4) -> list[Sector]:
    """Sectors of ``map_model`` for a sonar of ``range_max``: rule 0 original, 1 or 2 relaxed."""
    if rule not in (0, 1, 2):
        raise ValueError(f"rule must be 0 (original), 1 or 2, got {rule!r}")
    if not (range_max > 0 and resolution > 0):
        raise ValueError(f"range_max and resolution must be > 0, got {range_max}, {resolution}")
    feats = map_features(map_model) if features is None else features
    x0, y0, x1, y1 = map_model.free.bounds
    nx, ny = int(np.ceil((x1 - x0) / resolution)), int(np.ceil((y1 - y0) / resolution))
    if nx * ny > 4_000_000:
        raise ValueError(f"sector grid of {nx}x{ny} cells is too fine; raise resolution ({resolution} m)")
    xs = x0 + (np.arange(nx) + 0.5) * resolution
    ys = y0 + (np.arange(ny) + 0.5) * resolution
    gx, gy = np.meshgrid(xs, ys)
    centres = np.stack([gx.ravel(), gy.ravel()], axis=1)
    inside = map_model.contains(centres)
    vis = visible_features(centres[inside], map_model, feats, range_max)
    _, sig = np.unique(np.packbits(vis, axis=1), axis=0, return_inverse=True)
    sig_grid = np.full(nx * ny, -1, dtype=np.int64)
    sig_grid[inside] = sig.ravel()
    labels, n_comp = _components(sig_grid.reshape(ny, nx))
    flat = labels.ravel()
    comp_feats = [frozenset()] * n_comp
    inside_idx = np.nonzero(inside)[0]
    first = {}
    for k, lab in enumerate(flat[inside_idx].tolist()):
        first.setdefault(lab, k)
    for lab, k in first.items():
        comp_feats[lab] = frozenset(np.nonzero(vis[k])[0].tolist())
    sizes = np.bincount(flat[flat >= 0], minlength=n_comp)
    adj = _adjacency(labels)
    groups = _Groups(comp_feats, sizes)
    _absorb_slivers(groups, adj, sizes, min_cells)
    if rule == 1:
        _merge_rule1(groups, adj, flat, centres, feats, n_comp)
    elif rule == 2:
        _merge_rule2(groups, adj)
    root = np.array([groups.find(i) for i in range(n_comp)], dtype=np.int64)
    # cells outside free space take the nearest inside cell's group, so sectors cover free space
    grid = np.where(flat >= 0, root[np.maximum(flat, 0)], -1).reshape(ny, nx)
    if (grid < 0).any():
        _, (iy, ix) = ndimage.distance_transform_edt(grid < 0, return_indices=True)
        grid = grid[iy, ix]
    sectors = []
    for g in sorted(set(root.tolist())):
        poly = _cells_polygon(grid == g, x0, y0, resolution).intersection(map_model.free)
        if poly.is_empty:
            continue
        sectors.append(Sector(poly, groups.union[g], groups.common[g]))
    return sectors


def _absorb_slivers(groups: _Groups, adj, sizes, min_cells: int) -> None:
    for i in np.argsort(sizes):
        if sizes[i] >= min_cells:
            break
        nbrs = [b if a == i else a for a, b in adj if i in (a, b)]
        if not nbrs:
            continue
        best = max(nbrs, key=lambda j: (len(groups.union[groups.find(j)] & groups.union[groups.find(i)]),
                                        groups.size[groups.find(j)]))
        keep = groups.union[groups.find(best)], groups.common[groups.find(best)]
        groups.merge(i, best)
        r = groups.find(i)
        groups.union[r], groups.common[r] = keep  # a sliver is a discretization artifact


def _merge_rule1(groups: _Groups, adj, flat, centres, feats, n_comp) -> None:
    closest = {}
    sums = np.zeros((n_comp, 2))
    np.add.at(sums, flat[flat >= 0], centres[flat >= 0])
    counts = np.maximum(np.bincount(flat[flat >= 0], minlength=n_comp), 1)
    for r in {groups.find(i) for i in range(n_comp)}:
        members = [i for i in range(n_comp) if groups.find(i) == r]
        c = sums[members].sum(axis=0) / counts[members].sum()
        vis = sorted(groups.common[r])
        closest[r] = min(vis, key=lambda f: float(np.linalg.norm(feats[f].point - c))) if vis else -1
    for a, b in sorted(adj):
        ra, rb = groups.find(a), groups.find(b)
        if ra != rb and closest[ra] == closest[rb]:
            groups.merge(ra, rb)
            closest[groups.find(ra)] = closest[ra]


def _merge_rule2(groups: _Groups, adj) -> None:
    while True:
        best, best_key = None, None
        for a, b in adj:
            ra, rb = groups.find(a), groups.find(b)
            if ra == rb:
                continue
            shared = groups.common[ra] & groups.common[rb]
            if not shared:
                continue
            key = (len(shared), groups.size[ra] + groups.size[rb], -min(ra, rb), -max(ra, rb))
            if best_key is None or key > best_key:
                best, best_key = (ra, rb), key
        if best is None:
            return
        groups.merge(*best)


def _cells_polygon(mask: np.ndarray, x0: float, y0: float, res: float):
    """Union of the cells of ``mask (ny, nx)`` as boxes of row runs."""
    boxes = []
    for iy in np.nonzero(mask.any(axis=1))[0]:
        row = np.concatenate([[False], mask[iy], [False]]).astype(np.int8)
        d = np.diff(row)
        starts, ends = np.nonzero(d == 1)[0], np.nonzero(d == -1)[0]
        boxes.append(np.stack([x0 + starts * res, np.full(len(starts), y0 + iy * res),
                               x0 + ends * res, np.full(len(starts), y0 + (iy + 1) * res)], axis=1))
    if not boxes:
        return shapely.Polygon()
    b = np.concatenate(boxes)
    return shapely.union_all(shapely.box(b[:, 0], b[:, 1], b[:, 2], b[:, 3]))


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
