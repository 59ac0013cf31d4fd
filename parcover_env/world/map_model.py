"""The map as geometry: free space, obstacle polygons and boundary segments for ray casting."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Point, Polygon, box
from shapely.ops import unary_union
from shapely.validation import explain_validity

from parcover_env.errors import ConfigError
from parcover_env.geometry import polygon_edges

if TYPE_CHECKING:
    from parcover_env.config import MapConfig, Scenario

__all__ = ["MapModel", "validate_geometry"]


def _polygon(coords, key: str) -> Polygon:
    poly = Polygon(coords)
    if not poly.is_valid:
        raise ConfigError("", key, f"invalid polygon ({explain_validity(poly)})")
    if poly.area <= 1e-9:
        raise ConfigError("", key, "degenerate polygon (zero area)")
    return poly


@dataclass(frozen=True, eq=False)
class MapModel:
    """Free space of a map. ``free`` is the floor minus walls and obstacles (shapely)."""

    free: Polygon | MultiPolygon
    bounds: tuple[float, float, float, float]

    @classmethod
    def from_config(cls, cfg: MapConfig, include_unknown: bool = True) -> MapModel:
        """Build the map; ``include_unknown`` adds the obstacles missing from the known map."""
        floor = _polygon(cfg.boundary, "map.boundary") if cfg.boundary else box(0, 0, *cfg.size)
        solids = [_polygon(p, f"map.obstacles[{i}]") for i, p in enumerate(cfg.obstacles)]
        half = cfg.wall_thickness / 2
        solids += [LineString(w).buffer(half, cap_style="square", join_style="mitre") for w in cfg.walls]
        if include_unknown:
            solids += [_polygon(p, f"map.unknown_obstacles[{i}]") for i, p in enumerate(cfg.unknown_obstacles)]
        free = floor.difference(unary_union(solids)) if solids else floor
        free = shapely.make_valid(free).buffer(0)
        if free.is_empty:
            raise ConfigError("", "map", "walls and obstacles leave no free space")
        return cls(free=free, bounds=tuple(float(b) for b in floor.bounds))

    @cached_property
    def segments(self) -> np.ndarray:
        """All boundary edges of the free space, ``(S, 4)`` — what rays and sonars hit."""
        rings = []
        for poly in getattr(self.free, "geoms", [self.free]):
            rings.append(poly.exterior.coords)
            rings.extend(i.coords for i in poly.interiors)
        return np.concatenate([polygon_edges(r) for r in rings]).astype(float)

    @cached_property
    def _prepared(self):
        shapely.prepare(self.free)
        return self.free

    def contains(self, points, margin: float = 0.0) -> np.ndarray:
        """Whether each point ``(N, 2)`` lies in free space at least ``margin`` from obstacles."""
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        inside = shapely.contains_xy(self._prepared, pts[:, 0], pts[:, 1])
        if margin > 0:
            inside &= shapely.distance(self.free.boundary, shapely.points(pts)) >= margin
        return inside

    def reachable_region(self, start, radius: float) -> Polygon | None:
        """Component of the free space eroded by ``radius`` that contains ``start``."""
        eroded = self.free.buffer(-radius)
        p = Point(start)
        for comp in getattr(eroded, "geoms", [eroded]):
            if comp.buffer(1e-9).contains(p):
                return comp
        return None


def validate_geometry(s: Scenario) -> None:
    """Geometric checks of a scenario; raises ConfigError naming the offending key."""
    cfg = s.map
    for key, pts in (("map.boundary", [cfg.boundary] if cfg.boundary else []),):
        for poly in pts:
            _polygon(poly, key)
    world = MapModel.from_config(cfg, include_unknown=True)
    known = MapModel.from_config(cfg, include_unknown=False)
    r = s.robot.radius
    x0, y0, x1, y1 = world.bounds
    start = (s.start.x, s.start.y)
    if not (x0 <= s.start.x <= x1 and y0 <= s.start.y <= y1):
        raise ConfigError("", "start", f"{start} lies outside the map bounds {world.bounds}")
    if not world.contains([start], margin=r)[0]:
        raise ConfigError("", "start", f"{start} is inside a wall or closer than the robot radius {r} m to one")
    region = world.reachable_region(start, r)
    if region is None:  # pragma: no cover - guarded by the check above
        raise ConfigError("", "start", "the robot does not fit at the start")
    seen = {}
    for i, k in enumerate(s.kpois):
        key = f"kpois[{i}]"
        if not (x0 <= k[0] <= x1 and y0 <= k[1] <= y1):
            raise ConfigError("", key, f"{k} lies outside the map bounds {world.bounds}")
        if not known.contains([k])[0] or not world.contains([k])[0]:
            raise ConfigError("", key, f"{k} lies inside a wall or obstacle")
        if k in seen:
            raise ConfigError("", key, f"duplicate of kpois[{seen[k]}]")
        seen[k] = i
        if region.distance(Point(k)) > s.kpoi_radius - 1e-6:
            raise ConfigError("", key, f"{k} is unreachable from the start by a robot of radius {r} m "
                              f"(no free path gets within kpoi_radius {s.kpoi_radius} m)")
    for i, kin in enumerate(s.kinects):
        from parcover_env.sensors.camera import CameraModel

        footprint = CameraModel.from_config(kin).footprint()
        if footprint.is_empty or not footprint.intersects(box(*world.bounds)):
            raise ConfigError("", f"kinects[{i}]", f"Kinect '{kin.name}' does not see the map's floor")
