"""Roadmap over free space with clearance: medial axis (MAPRM-like) or grid, as a networkx graph.

Pipeline (all in metres, one raster used only internally):

1. Rasterize the free space eroded by ``clearance`` at ``resolution``: a cell is free when its
   centre lies in ``free.buffer(-clearance)``. Only the 8-connected component of the start is kept.
2. Skeleton: ``kind="medial_axis"`` takes :func:`skimage.morphology.medial_axis` of that mask (seed
   B's MAPRM idea: nodes on the medial axis have maximal clearance); ``kind="grid"`` keeps every cell.
3. Terminals: the start and each KPOI are attached to the nearest free cell (a KPOI within
   ``kpoi_radius`` of a free cell counts, as the env counts a visit within that radius). A terminal
   off the skeleton is joined to it by a geodesic spur through free cells (multi-source Dijkstra).
4. Chains of degree-2 cells are contracted into single edges carrying their polyline (``path``) so
   the graph stays small: nodes are junctions, dead ends and terminals.

The clearance margin: consecutive cell centres are at most ``resolution * sqrt(2)`` apart, so a
straight segment between them keeps ``clearance - 0.71 * resolution`` from obstacles. The planner
therefore uses ``clearance = radius + 0.75 * resolution + 0.005`` (see :func:`planner_clearance`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import networkx as nx
import numpy as np
import shapely
from scipy import ndimage, sparse
from scipy.sparse import csgraph
from skimage.morphology import medial_axis

from parcover_env.errors import ParcoverError
from parcover_env.world.map_model import MapModel

__all__ = ["Roadmap", "UnreachableKpoiError", "build_roadmap", "edge_polyline", "planner_clearance",
           "ROADMAP_KINDS"]

ROADMAP_KINDS = ("medial_axis", "grid")
_SQ2 = math.sqrt(2.0)


class UnreachableKpoiError(ParcoverError, ValueError):
    """A KPOI (``index``; -1 for the start) cannot be connected to the roadmap."""

    def __init__(self, index: int, message: str):
        self.index = index
        super().__init__(message)


def planner_clearance(radius: float, resolution: float) -> float:
    """Raster clearance that guarantees ``radius`` along straight moves between cell centres."""
    return float(radius) + 0.75 * float(resolution) + 0.005


@dataclass(frozen=True, eq=False)
class Roadmap:
    """Graph over free space. Nodes are ints with ``pos`` (x, y); edges carry ``weight`` (m) and
    ``path`` (K, 2) polyline oriented from node ``src``. ``start`` / ``kpois`` are node ids."""

    graph: nx.Graph
    start: int
    kpois: tuple[int, ...]
    start_point: tuple[float, float]
    kpoi_points: np.ndarray
    clearance: float
    resolution: float
    kind: str

    def node_pos(self, node: int) -> np.ndarray:
        return np.asarray(self.graph.nodes[node]["pos"], dtype=float)


def edge_polyline(graph: nx.Graph, u, v) -> np.ndarray:
    """Polyline ``(K, 2)`` of edge (u, v) oriented from ``u`` to ``v`` (straight if no ``path``)."""
    data = graph.edges[u, v]
    path = data.get("path")
    if path is None:
        return np.array([graph.nodes[u]["pos"], graph.nodes[v]["pos"]], dtype=float)
    return path if data.get("src", u) == u else path[::-1]


def _neighbour_csr(cells: np.ndarray, res: float, drop_diagonal) -> sparse.csr_matrix:
    """8-connected graph over ``cells`` (bool raster); ``drop_diagonal(pad, di, dj)`` masks diagonals."""
    h, w = cells.shape
    pad = np.zeros((h + 2, w + 2), bool)
    pad[1:-1, 1:-1] = cells
    ids = np.arange(h * w).reshape(h, w)
    rows, cols, vals = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        nb_ids = np.full((h + 2, w + 2), -1)
        nb_ids[1:-1, 1:-1] = ids
        ok = cells & pad[1 + di: h + 1 + di, 1 + dj: w + 1 + dj]
        if di and dj:
            ok &= ~drop_diagonal(pad, di, dj)
        ia = ids[ok]
        ib = nb_ids[1 + di: h + 1 + di, 1 + dj: w + 1 + dj][ok]
        length = res * (_SQ2 if di and dj else 1.0)
        rows += [ia, ib]
        cols += [ib, ia]
        vals += [np.full(len(ia), length)] * 2
    return sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(h * w, h * w))


def _grid_csr(mask: np.ndarray, res: float) -> sparse.csr_matrix:
    """8-connected grid graph over ``mask`` cells (diagonals only when both orthogonals are free)."""
    h, w = mask.shape
    return _neighbour_csr(mask, res, lambda pad, di, dj: ~(pad[1 + di: h + 1 + di, 1: w + 1]
                                                           & pad[1: h + 1, 1 + dj: w + 1 + dj]))


def _skeleton_csr(skel: np.ndarray, res: float) -> sparse.csr_matrix:
    """8-connected skeleton graph without redundant diagonals (a diagonal is dropped when an
    orthogonal pair of skeleton cells already joins its ends)."""
    h, w = skel.shape
    return _neighbour_csr(skel, res, lambda pad, di, dj: (pad[1 + di: h + 1 + di, 1: w + 1]
                                                          | pad[1: h + 1, 1 + dj: w + 1 + dj]))


def _nearest_cell(mask: np.ndarray, origin: tuple[float, float], res: float, point, max_dist: float):
    """Flat index of the free cell whose centre is nearest ``point`` within ``max_dist``, or None."""
    h, w = mask.shape
    x0, y0 = origin
    n = int(math.ceil(max_dist / res)) + 1
    cj = int(math.floor((point[0] - x0) / res))
    ci = int(math.floor((point[1] - y0) / res))
    i0, i1 = max(0, ci - n), min(h, ci + n + 1)
    j0, j1 = max(0, cj - n), min(w, cj + n + 1)
    if i0 >= i1 or j0 >= j1:
        return None
    ii, jj = np.nonzero(mask[i0:i1, j0:j1])
    if len(ii) == 0:
        return None
    ii, jj = ii + i0, jj + j0
    d = np.hypot(x0 + (jj + 0.5) * res - point[0], y0 + (ii + 0.5) * res - point[1])
    k = int(np.argmin(d))
    return int(ii[k] * w + jj[k]) if d[k] <= max_dist else None


def _contract(adj: sparse.csr_matrix, nodes: np.ndarray, terminals: set[int], centres) -> nx.Graph:
    """Contract chains of degree-2 non-terminal cells into edges with polylines."""
    indptr, indices, data = adj.indptr, adj.indices, adj.data
    deg = np.diff(indptr)
    g = nx.Graph()
    is_key = {int(n): (deg[n] != 2 or int(n) in terminals) for n in nodes}
    for u in nodes:
        u = int(u)
        if not is_key[u]:
            continue
        g.add_node(u, pos=tuple(centres(u)))
    for u in list(g.nodes):
        for k in range(indptr[u], indptr[u + 1]):
            chain, length = [u, int(indices[k])], float(data[k])
            while not is_key[chain[-1]]:
                cur, prev = chain[-1], chain[-2]
                a, b = indptr[cur], indptr[cur + 1]
                nxt_k = a if indices[a] != prev else a + 1
                if nxt_k >= b:  # pragma: no cover - degree-2 guaranteed
                    break
                chain.append(int(indices[nxt_k]))
                length += float(data[nxt_k])
            v = chain[-1]
            if v == u or (u, chain[1]) > (v, chain[-2]):
                continue  # self-loop without terminals, or the same chain seen from its other end
            if g.has_edge(u, v) and g.edges[u, v]["weight"] <= length:
                continue  # a parallel longer chain holds no terminal: never on a shortest path
            pts = np.array([centres(c) for c in chain], dtype=float)
            pts.setflags(write=False)
            g.add_edge(u, v, weight=length, path=pts, src=u)
    return g


def build_roadmap(map_model: MapModel, start, kpois, clearance: float, resolution: float,
                  kind: str = "medial_axis", kpoi_radius: float = 0.25) -> Roadmap:
    """Roadmap of ``map_model`` for a disc robot needing ``clearance`` (m), with ``start`` and
    ``kpois (n, 2)`` connected in. Raises :class:`UnreachableKpoiError` naming the KPOI index
    (``-1`` = the start) that cannot be connected within ``kpoi_radius``."""
    if kind not in ROADMAP_KINDS:
        raise ValueError(f"roadmap kind must be one of {ROADMAP_KINDS}, got {kind!r}")
    if not (resolution > 0 and clearance >= 0 and kpoi_radius > 0):
        raise ValueError("resolution and kpoi_radius must be > 0 and clearance >= 0, got "
                         f"{resolution}, {kpoi_radius}, {clearance}")
    kp = np.asarray(kpois, dtype=float).reshape(-1, 2) if len(kpois) else np.zeros((0, 2))
    if not np.all(np.isfinite(kp)) or not np.all(np.isfinite(np.asarray(start, dtype=float))):
        raise ValueError("start and kpois must be finite (x, y) points")
    x0, y0, x1, y1 = map_model.bounds
    w, h = int(math.ceil((x1 - x0) / resolution)), int(math.ceil((y1 - y0) / resolution))
    xs = x0 + (np.arange(w) + 0.5) * resolution
    ys = y0 + (np.arange(h) + 0.5) * resolution
    eroded = map_model.free.buffer(-clearance)
    if eroded.is_empty:
        raise UnreachableKpoiError(-1, f"no free space keeps a clearance of {clearance:.3f} m")
    shapely.prepare(eroded)
    gx, gy = np.meshgrid(xs, ys)
    mask = shapely.contains_xy(eroded, gx, gy)

    def centres(flat: int) -> tuple[float, float]:
        return float(xs[flat % w]), float(ys[flat // w])

    reach_dist = max(kpoi_radius, 2.0 * resolution)
    s_cell = _nearest_cell(mask, (x0, y0), resolution, start, reach_dist)
    if s_cell is None:
        raise UnreachableKpoiError(-1, f"start {tuple(start)} is not within {reach_dist:.2f} m of free space "
                                   f"with clearance {clearance:.3f} m")
    labels, _ = ndimage.label(mask, structure=np.ones((3, 3), bool))
    comp = labels == labels.flat[s_cell]
    k_cells = []
    for i, p in enumerate(kp):
        c = _nearest_cell(comp, (x0, y0), resolution, p, kpoi_radius)
        if c is None:
            raise UnreachableKpoiError(i, f"no point within kpoi_radius {kpoi_radius} m of {tuple(p)} is "
                                       f"reachable from the start with clearance {clearance:.3f} m")
        k_cells.append(c)
    terminals = {s_cell, *k_cells}
    if kind == "grid":
        adj = _grid_csr(comp, resolution)
        nodes = np.flatnonzero(comp)
    else:
        skel = medial_axis(comp, rng=0) & comp  # fixed tie-breaking: deterministic roadmap
        if not skel.any():
            skel.flat[s_cell] = True
        adj = _skeleton_csr(skel, resolution)
        off = [c for c in terminals if not skel.flat[c]]
        nodes_set = set(np.flatnonzero(skel).tolist())
        if off:
            grid = _grid_csr(comp, resolution)
            _, pred, _ = csgraph.dijkstra(grid, indices=np.flatnonzero(skel), min_only=True,
                                          return_predecessors=True)
            extra_r, extra_c = [], []
            for t in off:
                cur = t
                while not skel.flat[cur]:
                    nxt = int(pred[cur])
                    if nxt < 0:  # pragma: no cover - same component as the skeleton
                        break
                    extra_r.append(cur)
                    extra_c.append(nxt)
                    nodes_set.add(cur)
                    cur = nxt
            er, ec = np.array(extra_r, int), np.array(extra_c, int)
            lengths = np.where((np.abs(er - ec) == 1) | (np.abs(er - ec) == w), resolution, resolution * _SQ2)
            spur = sparse.csr_matrix((np.concatenate([lengths, lengths]),
                                      (np.concatenate([er, ec]), np.concatenate([ec, er]))), shape=adj.shape)
            adj = adj.maximum(spur).tocsr()
        nodes = np.array(sorted(nodes_set), dtype=int)
    graph = _contract(adj, nodes, terminals, centres)
    graph.graph.update(clearance=clearance, resolution=resolution, kind=kind)
    return Roadmap(graph=graph, start=int(s_cell), kpois=tuple(int(c) for c in k_cells),
                   start_point=(float(start[0]), float(start[1])), kpoi_points=kp, clearance=float(clearance),
                   resolution=float(resolution), kind=kind)
