"""Multi-Kinect connection tree (Min et al. Alg. 2).

Each Kinect sees a floor polygon (its footprint). Walking the plan tree from the start, every time a
path leaves the Kinect it was in and enters another one (or enters one after a stretch seen by
none), that is a crossing from the first to the second: an output of the first and an input of the
second. Crossings between the same ordered pair are counted on one link. The root is the Kinect
containing the start (nearest footprint centroid if several); a breadth-first search over the links
in travel direction gives each reached Kinect its parent. Where footprints overlap, a path keeps
the Kinect it is in until it leaves it (hysteresis), so a narrow overlap is one crossing, not many.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import shapely
from shapely.geometry import Point, Polygon

from parcover_env.planning.plan import Plan

if TYPE_CHECKING:
    from parcover_env.config import Scenario

__all__ = ["KinectTree", "kinect_tree", "kinect_footprints", "plan_summary"]


@dataclass(frozen=True)
class KinectTree:
    """Tree of Kinects rooted at the one seeing the start, with crossing counts per link."""

    root: str | None
    parent: dict[str, str | None]
    """Reached Kinects -> parent (None for the root and for Kinects first entered from unseen floor)."""
    children: dict[str, tuple[str, ...]]
    links: dict[tuple[str, str], int]
    """(from, to) -> number of plan-tree crossings from ``from`` into ``to`` (all adjacencies)."""
    unreached: tuple[str, ...]
    tp_cover: tuple[tuple[str, ...], ...]
    """Kinects seeing each turning position (same order as ``plan.turning_points``)."""
    kpoi_cover: tuple[tuple[str, ...], ...]
    """Kinects seeing the spot where each KPOI is visited (index = KPOI index)."""

    def inputs(self, name: str) -> int:
        return sum(c for (a, b), c in self.links.items() if b == name)

    def outputs(self, name: str) -> int:
        return sum(c for (a, b), c in self.links.items() if a == name)

    def edges(self) -> list[list[str]]:
        """Adjacent Kinect pairs as sorted ``[a, b]`` (Min et al. Fig. 6(b): "A is connected with B, C
        and D, and B with D"), whatever the direction the plan crosses them in."""
        return [list(p) for p in sorted({tuple(sorted(k)) for k in self.links})]

    def to_dict(self) -> dict[str, Any]:
        return {"root": self.root, "parent": dict(self.parent),
                "children": {k: list(v) for k, v in self.children.items()},
                "links": [[a, b, c] for (a, b), c in self.links.items()], "unreached": list(self.unreached),
                "tp_cover": [list(c) for c in self.tp_cover],
                "kpoi_cover": [list(c) for c in self.kpoi_cover]}


def kinect_footprints(scenario: Scenario) -> dict[str, Polygon]:
    """Floor footprint of every Kinect of the scenario (name -> shapely polygon)."""
    from parcover_env.geometry.camera import CameraModel

    return {k.name: CameraModel.from_config(k).footprint() for k in scenario.kinects}


def _densify(poly: np.ndarray, step: float) -> np.ndarray:
    pts = [poly[:1]]
    for a, b in zip(poly[:-1], poly[1:], strict=False):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        t = np.arange(1, n + 1)[:, None] / n
        pts.append(a + t * (b - a))
    return np.concatenate(pts)


def kinect_tree(footprints: dict[str, Polygon], plan: Plan, start, step: float = 0.05) -> KinectTree:
    """Alg. 2 over ``plan.tree``: links between Kinects crossed by the plan, tree from the root."""
    if not footprints:
        raise ValueError("kinect_tree needs at least one Kinect footprint")
    if not (step > 0):
        raise ValueError(f"step must be > 0, got {step}")
    names = sorted(footprints)
    for n in names:
        if not isinstance(footprints[n], Polygon | shapely.MultiPolygon):
            raise ValueError(f"footprint of Kinect {n!r} must be a shapely polygon")
    polys = [footprints[n] for n in names]
    for p in polys:
        shapely.prepare(p)

    def inside(pts: np.ndarray) -> np.ndarray:  # (P, K) membership
        return np.stack([shapely.contains_xy(p, pts[:, 0], pts[:, 1]) for p in polys], axis=1)

    sx, sy = float(start[0]), float(start[1])
    at_start = [i for i, p in enumerate(polys) if p.covers(Point(sx, sy))]
    root = None
    if at_start:
        root_i = min(at_start, key=lambda i: polys[i].centroid.distance(Point(sx, sy)))
        root = names[root_i]
    tree = plan.tree
    links: dict[tuple[str, str], int] = {}
    entered_from_none: list[str] = []
    state = {0: (root, root is not None)}  # tree node -> (last Kinect, currently inside it)
    for node in range(1, tree.n_nodes):  # pre-order: parents come first
        last, is_in = state[tree.parent[node]]
        pts = _densify(np.asarray(tree.edge_paths[node], dtype=float), step)
        member = inside(pts)
        for row in member:
            if last is not None and row[names.index(last)]:
                is_in = True
                continue
            hits = np.flatnonzero(row)
            if len(hits) == 0:
                is_in = False
                continue
            new = names[int(hits[0])]
            if last is None:
                entered_from_none.append(new)
            elif new != last:
                links[(last, new)] = links.get((last, new), 0) + 1
            last, is_in = new, True
        state[node] = (last, is_in)
    parent: dict[str, str | None] = {}
    children: dict[str, list[str]] = {}
    queue = deque()
    for r in ([root] if root else []) + entered_from_none:
        if r not in parent:
            parent[r] = None
            queue.append(r)
    while queue:
        a = queue.popleft()
        children.setdefault(a, [])
        for (u, v) in links:
            if u == a and v not in parent:
                parent[v] = a
                children[a].append(v)
                queue.append(v)
    tp_pts = np.array([tp.position for tp in plan.turning_points], dtype=float).reshape(-1, 2)
    tp_member = inside(tp_pts) if len(tp_pts) else np.zeros((0, len(names)), bool)
    kp_pos = np.full((plan.n_kpois, 2), np.nan)
    for node, ks in enumerate(tree.kpois):
        for k in ks:
            kp_pos[k] = tree.positions[node]
    kp_member = inside(np.nan_to_num(kp_pos, nan=1e18))
    return KinectTree(root=root, parent=parent, children={k: tuple(v) for k, v in children.items()},
                      links=links, unreached=tuple(n for n in names if n not in parent),
                      tp_cover=tuple(tuple(names[i] for i in np.flatnonzero(r)) for r in tp_member),
                      kpoi_cover=tuple(tuple(names[i] for i in np.flatnonzero(r)) for r in kp_member))


def plan_summary(plan: Plan, tree: KinectTree | None = None) -> dict[str, Any]:
    """The plan as scripts want it (``parcover plan --json``): ``n_robots``, ``c_max``, ``c_p`` (the
    roadmap metric), ``c_route`` (the same along the driven route polylines), ``c_free`` (the
    free-space lower bound, :attr:`Plan.c_free`), ``method``, ``turning_positions``
    ``[[x, y], ...]``, ``tp_branches`` (robots per branch of each TP,
    the numbers beside the TPs of Min et al. Fig. 6(c)), ``kinect_tree`` (adjacent Kinect pairs, empty
    without Kinects), ``kinect_root``, ``kinect_links`` ``[[from, to, crossings], ...]`` and ``routes``
    (per robot: ``kpois`` in visiting order, ``cost`` on the roadmap metric, ``path`` ``[[x, y], ...]``)."""
    return {
        "n_robots": plan.r, "c_max": float(plan.c_max), "c_p": float(plan.c_p),
        "c_route": float(plan.c_route), "c_free": float(plan.c_free), "method": plan.method,
        "n_leaves": plan.n_leaves,
        "turning_positions": [[float(tp.position[0]), float(tp.position[1])] for tp in plan.turning_points],
        "tp_branches": [[b.n_robots for b in tp.branches] for tp in plan.turning_points],
        "kinect_tree": tree.edges() if tree is not None else [],
        "kinect_root": tree.root if tree is not None else None,
        "kinect_links": [[a, b, int(c)] for (a, b), c in sorted(tree.links.items())] if tree is not None else [],
        "routes": [{"robot": rp.index, "kpois": list(rp.kpois), "cost": float(rp.cost), "path": rp.path.tolist()}
                   for rp in plan.robots],
    }
