"""Typed, JSON-friendly result of the PPCP planner: robots' paths, the plan tree, turning positions.

Robot numbering: robots are ordered by a depth-first traversal of the plan tree, so the robots
travelling along any branch form a contiguous index range ``[lo, hi)`` and the team can leave the
start in ONE column and split into contiguous blocks at each turning position (TP). The leader of
a block is its first robot ``lo``. Robots whose route ends at a node are ordered after the robots
that continue from it, so a leader never has to stop in front of its followers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Branch", "TurningPoint", "PlanTree", "RobotPlan", "Plan"]


def _pt(p) -> list[float]:
    return [float(p[0]), float(p[1])]


@dataclass(frozen=True)
class Branch:
    """One way out of a TP: the robots ``[lo, hi)`` taking it, led by robot ``leader``."""

    next_waypoint: tuple[float, float]
    """First point after the TP on this branch (the TP itself for robots whose route ends there)."""
    robots: tuple[int, int]
    leader: int
    child: int
    """Plan-tree node the branch leads to (the TP's own node for robots ending there)."""

    @property
    def n_robots(self) -> int:
        return self.robots[1] - self.robots[0]

    def to_dict(self) -> dict[str, Any]:
        return {"next_waypoint": _pt(self.next_waypoint), "robots": list(self.robots),
                "leader": self.leader, "n_robots": self.n_robots, "child": self.child}


@dataclass(frozen=True)
class TurningPoint:
    """A plan-tree node where the set of robots travelling together splits."""

    node: int
    """Index in :class:`PlanTree`."""
    position: tuple[float, float]
    distance: float
    """Distance (m) along the path of every robot in ``robots`` at which the TP is reached."""
    robots: tuple[int, int]
    """Robots ``[lo, hi)`` arriving together; the first is the leader."""
    branches: tuple[Branch, ...]

    def to_dict(self) -> dict[str, Any]:
        return {"node": self.node, "position": _pt(self.position), "distance": self.distance,
                "robots": list(self.robots), "leader": self.robots[0],
                "branches": [b.to_dict() for b in self.branches]}


@dataclass(frozen=True, eq=False)
class PlanTree:
    """The tree travelled by the team (paper Fig. 6c): root = start; nodes = TPs, KPOI visits and
    route ends; each node holds the polyline from its parent and the robots passing through it."""

    positions: np.ndarray
    """(N, 2) world positions (m)."""
    parent: tuple[int, ...]
    """Parent index, -1 for the root (node 0)."""
    edge_paths: tuple[np.ndarray, ...]
    """Polyline (K, 2) from the parent to the node (a single point for the root)."""
    robots: tuple[tuple[int, int], ...]
    """Robot range ``[lo, hi)`` travelling through each node."""
    distance: np.ndarray
    """(N,) distance from the start along the paths (m)."""
    kpois: tuple[tuple[int, ...], ...]
    """KPOIs (indices into the scenario's list) visited at each node."""
    roadmap_node: tuple[int, ...]

    @property
    def n_nodes(self) -> int:
        return len(self.parent)

    def children(self, i: int) -> list[int]:
        return [j for j, p in enumerate(self.parent) if p == i]

    def to_dict(self) -> dict[str, Any]:
        return {"positions": self.positions.tolist(), "parent": list(self.parent),
                "edge_paths": [p.tolist() for p in self.edge_paths], "robots": [list(r) for r in self.robots],
                "distance": self.distance.tolist(), "kpois": [list(k) for k in self.kpois]}


@dataclass(frozen=True, eq=False)
class RobotPlan:
    """One robot's route: polyline, ordered KPOIs (its own, disjoint from the others') and cost."""

    index: int
    kpois: tuple[int, ...]
    """KPOIs this robot is credited with, in visiting order (indices into the scenario's list)."""
    kpoi_distance: tuple[float, ...]
    """Distance along ``path`` (m) at which each of ``kpois`` is reached."""
    path: np.ndarray
    """(K, 2) world polyline from the start (m); straight segments keep the robot's clearance."""
    cost: float
    """Cost on the roadmap metric (what the planner optimizes, comparable with ``c_max``)."""
    length: float
    """Length of ``path`` (m); <= ``cost`` after smoothing."""
    tree_nodes: tuple[int, ...]
    """Plan-tree nodes from the root to the route's end."""

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "kpois": list(self.kpois), "kpoi_distance": list(self.kpoi_distance),
                "path": self.path.tolist(), "cost": self.cost, "length": self.length,
                "tree_nodes": list(self.tree_nodes)}


@dataclass(frozen=True, eq=False)
class Plan:
    """PPCP solution. ``c_max`` (lower bound ON THE ROADMAP METRIC: roadmap distance from the start
    to the furthest KPOI), ``c_p`` (max route cost, same metric), ``r`` robots with disjoint KPOI
    sets covering all KPOIs; ``c_free`` the free-space lower bound beside ``c_max``."""

    c_max: float
    c_p: float
    robots: tuple[RobotPlan, ...]
    tree: PlanTree
    turning_points: tuple[TurningPoint, ...]
    n_kpois: int
    method: str
    """``paths`` (stage 1), ``tours`` (stage 2), ``minmax`` (given r) or ``exact`` / ``exact_minmax``."""
    furthest_kpoi: int
    n_leaves: int = 0
    """Stage-1 robots: leaves of the pruned shortest-path tree (KPOIs with no KPOI below them)."""
    c_free: float = float("nan")
    """Free-space lower bound (m): the longest over KPOIs of the shortest path of the robot's
    centre from the start to the KPOI through the free space eroded by the robot radius
    (:func:`~parcover_env.planning.free_space.free_space_distances`); no route is shorter. ``c_max``
    measures the same on the roadmap, which keeps to the middle of the free space: ``c_free <=
    c_max``. NaN when the plan was solved on a bare graph (:func:`solve_ppcp`), set by
    :func:`~parcover_env.planning.scenario_plan.plan_scenario`."""

    @property
    def r(self) -> int:
        return len(self.robots)

    @property
    def paths(self) -> list[np.ndarray]:
        return [rp.path for rp in self.robots]

    @property
    def c_route(self) -> float:
        """Longest distance (m) along a robot's route polyline (the smoothed path it drives) from
        the start to one of its KPOIs: between ``c_free`` and ``c_max`` on a plan at ``c_p = c_max``."""
        return max((d for rp in self.robots for d in rp.kpoi_distance), default=0.0)

    def kpoi_owner(self) -> np.ndarray:
        """(n_kpois,) index of the robot credited with each KPOI."""
        owner = np.full(self.n_kpois, -1, dtype=int)
        for rp in self.robots:
            owner[list(rp.kpois)] = rp.index
        return owner

    def to_dict(self) -> dict[str, Any]:
        """Plain lists / floats / ints only (JSON-serializable)."""
        return {"r": self.r, "c_max": self.c_max, "c_p": self.c_p, "c_free": self.c_free,
                "c_route": self.c_route, "method": self.method,
                "n_kpois": self.n_kpois, "furthest_kpoi": self.furthest_kpoi,
                "n_leaves": self.n_leaves,
                "robots": [rp.to_dict() for rp in self.robots],
                "turning_points": [tp.to_dict() for tp in self.turning_points],
                "tree": self.tree.to_dict()}
