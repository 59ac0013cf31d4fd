"""The Mission of a scenario: maps, PPCP plan, start poses and routes — built once, shared.

The env and the scripted expert both take their routes, turning positions and tolerances from
one :class:`Mission` (``mission_for(scenario)``, cached per process), so nothing about the plan is
ever rebuilt from copied numbers.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from parcover_env.config import Scenario
from parcover_env.planning import Plan, plan_scenario
from parcover_env.scenarios.progress import RouteTracker
from parcover_env.world.map_model import MapModel, map_model
from parcover_env.world.placement import queue_poses, start_poses

__all__ = ["Mission", "mission_for"]


def _length(poly: np.ndarray) -> float:
    return float(np.hypot(*np.diff(poly, axis=0).T).sum()) if len(poly) > 1 else 0.0


def _lead_in(queue, xy: np.ndarray) -> np.ndarray:
    """Waypoints from a robot's place in the start queue up the queue to the start (excluded)."""
    if not queue:
        return np.empty((0, 2))
    pts = np.asarray(queue, dtype=float)
    seg = np.diff(pts, axis=0)
    # the queue segment holding xy: the one it is closest to
    rel = xy - pts[:-1]
    u = np.clip(np.einsum("ij,ij->i", rel, seg) / np.einsum("ij,ij->i", seg, seg), 0.0, 1.0)
    k = int(np.argmin(np.hypot(*(pts[:-1] + u[:, None] * seg - xy).T)))
    return np.vstack([xy, pts[k:0:-1]])


@dataclass(frozen=True, eq=False)
class Mission:
    """Static description of one scenario's mission (read-only; share freely).

    ``routes[i]`` is robot i's polyline: a lead-in from its place in the start queue, then its
    plan path through its KPOIs. ``lead_in_lengths[i]`` is the lead-in's length (m).
    """

    scenario: Scenario
    map: MapModel
    """The true map, with obstacles the robots do not know about."""
    known_map: MapModel
    """The map the planner and the expert know."""
    plan: Plan
    start_poses: np.ndarray
    routes: tuple[np.ndarray, ...]
    lead_in_lengths: np.ndarray

    @property
    def n_robots(self) -> int:
        return self.plan.r

    @property
    def kpois(self) -> np.ndarray:
        return np.array(self.scenario.kpois, dtype=float)

    @property
    def waypoint_tol(self) -> float:
        """How close (m) a robot must come to a KPOI vertex of its route before moving on."""
        r = self.scenario.robot.radius
        return min(max(0.15, 1.5 * r), 0.6 * self.scenario.kpoi_radius)

    @property
    def lookahead(self) -> float:
        """Pure-pursuit look-ahead distance (m) of the route goal."""
        return max(0.3, 2.5 * self.scenario.robot.radius)

    @property
    def reach_tol(self) -> float:
        """How close (m) a leader must come to its TP for the split (Alg. 1)."""
        return max(0.15, 1.5 * self.scenario.robot.radius)

    def tracker(self, routes: list[np.ndarray] | None = None, offsets: np.ndarray | None = None) -> RouteTracker:
        """A fresh per-episode progress tracker over this mission's routes (or given ``routes``)."""
        if routes is None:
            routes, offsets = list(self.routes), self.lead_in_lengths
        return RouteTracker(self.kpois, self.scenario.kpoi_radius, routes, waypoint_tol=self.waypoint_tol,
                            offsets=offsets, lookahead=self.lookahead)


def build_mission(s: Scenario) -> Mission:
    """Plan and lay out ``s`` (uncached: use :func:`mission_for`)."""
    world, known = map_model(s.map, True), map_model(s.map, False)
    plan = plan_scenario(s, s.n_robots_fixed)
    n = plan.r
    if s.start_queue:
        poses = queue_poses(world, s.queue, n, s.robot.radius, s.formation.spacing, s.source)
        poses[0, 2] = s.start.theta
    else:
        poses = start_poses(world, (s.start.x, s.start.y, s.start.theta), n, s.robot.radius,
                            s.formation.spacing, s.source)
    poses.setflags(write=False)
    lead_ins = [_lead_in(s.queue, p[:2]) for p in poses]
    routes = tuple(np.vstack([li, path]) for li, path in zip(lead_ins, plan.paths))
    for r in routes:
        r.setflags(write=False)
    lengths = np.array([_length(np.vstack([li, path[:1]])) for li, path in zip(lead_ins, plan.paths)])
    lengths.setflags(write=False)
    return Mission(s, world, known, plan, poses, routes, lengths)


@lru_cache(maxsize=32)
def mission_for(scenario: Scenario) -> Mission:
    """The Mission of ``scenario``, built once per process."""
    return build_mission(scenario)
