"""One call for the env and the CLI: the plan of a scenario on its KNOWN map (cached)."""

from __future__ import annotations

import dataclasses
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import LineString

from parcover_env.config.schema import MAX_ROBOTS
from parcover_env.errors import ArgumentError, ConfigError
from parcover_env.planning.free_space import free_space_distances
from parcover_env.planning.plan import Plan
from parcover_env.planning.ppcp import solve_ppcp
from parcover_env.planning.roadmap import Roadmap, UnreachableKpoiError, build_roadmap, planner_clearance
from parcover_env.world.map_model import MapModel, map_model

if TYPE_CHECKING:
    from parcover_env.config import Scenario

__all__ = ["free_space_bound", "plan_scenario", "scenario_roadmap", "make_simplifier", "path_is_clear"]


def path_is_clear(region, points: np.ndarray) -> bool:
    """Whether the polyline stays inside ``region`` (the free space eroded by the robot radius)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    geom = LineString(pts) if len(pts) > 1 else shapely.points(pts[0])
    return bool(region.covers(geom))


def make_simplifier(map_model: MapModel, radius: float, tolerance: float):
    """Douglas–Peucker smoothing (endpoints kept) accepted only if the result keeps ``radius`` from
    every obstacle; otherwise tighter tolerances, finally the raw polyline."""
    region = map_model.free.buffer(-(radius - 1e-6))
    shapely.prepare(region)

    def simplify(points: np.ndarray) -> np.ndarray:
        pts = np.asarray(points, dtype=float)
        if len(pts) <= 2:
            return pts
        line = LineString(pts)
        for tol in (4 * tolerance, tolerance, 0.25 * tolerance):
            cand = np.asarray(line.simplify(tol, preserve_topology=False).coords, dtype=float)
            if len(cand) >= 2 and path_is_clear(region, cand):
                return cand
        return pts

    return simplify


@lru_cache(maxsize=32)
def _cached_roadmap(map_cfg, start, kpois, radius: float, resolution: float, kind: str,
                    kpoi_radius: float) -> Roadmap:
    model = map_model(map_cfg, include_unknown=False)
    return build_roadmap(model, start, kpois, planner_clearance(radius, resolution), resolution, kind,
                         kpoi_radius)


def scenario_roadmap(scenario: Scenario) -> Roadmap:
    """Roadmap of the scenario's known map (cached); ConfigError names an unreachable KPOI."""
    try:
        return _cached_roadmap(scenario.map, (scenario.start.x, scenario.start.y), tuple(scenario.kpois),
                               scenario.robot.radius, scenario.planner.resolution, scenario.planner.roadmap,
                               scenario.kpoi_radius)
    except UnreachableKpoiError as exc:
        key = "start" if exc.index < 0 else f"kpois[{exc.index}]"
        raise ConfigError(scenario.source, key, str(exc)) from None


@lru_cache(maxsize=32)
def _cached_plan(scenario: Scenario, n_robots: int | None, method: str) -> Plan:
    roadmap = scenario_roadmap(scenario)
    model = map_model(scenario.map, include_unknown=False)
    radius = scenario.robot.radius
    simplify = make_simplifier(model, radius, scenario.planner.resolution)
    start = np.array([scenario.start.x, scenario.start.y])
    region = model.free.buffer(-(radius - 1e-6))
    to_roadmap = np.vstack([start, roadmap.node_pos(roadmap.start)])
    start_point = start if path_is_clear(region, to_roadmap) else None
    plan = solve_ppcp(roadmap.graph, roadmap.start, roadmap.kpois, n_robots, method=method,
                      start_point=start_point, simplify=simplify, tp_merge_tol=scenario.planner.tp_merge_tol)
    return dataclasses.replace(plan, c_free=free_space_bound(scenario))


@lru_cache(maxsize=32)
def free_space_bound(scenario: Scenario) -> float:
    """The scenario's free-space lower bound ``c_free`` (m, :attr:`Plan.c_free`): the longest over
    its KPOIs of the shortest path from the start through the known map's free space eroded by
    the robot radius (:func:`~parcover_env.planning.free_space.free_space_distances`)."""
    if not scenario.kpois:
        return 0.0
    model = map_model(scenario.map, include_unknown=False)
    d = free_space_distances(model.free, (scenario.start.x, scenario.start.y), scenario.kpois, scenario.robot.radius)
    return float(d.max())


def plan_scenario(scenario: Scenario, n_robots: int | None = None, method: str = "auto") -> Plan:
    """PPCP plan of ``scenario`` on its known map (unknown obstacles are not in the planner's map).

    ``n_robots=None`` -> fewest robots at ``c_p = c_max``; an int -> min–max routes for that many.
    Paths keep the robot radius from known obstacles. Cached per (scenario, n_robots, method).
    """
    if n_robots is not None and (isinstance(n_robots, bool) or int(n_robots) != n_robots
                                 or not 1 <= n_robots <= MAX_ROBOTS):
        raise ArgumentError(f"n_robots must be an integer in [1, {MAX_ROBOTS}] or None, got {n_robots!r}")
    return _cached_plan(scenario, None if n_robots is None else int(n_robots), method)
