"""The map as geometry: free space, obstacle polygons and boundary segments for ray casting."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Point, Polygon, box
from shapely.ops import unary_union
from shapely.validation import explain_validity

from parcover_env.errors import ConfigError
from parcover_env.geometry import polygon_edges

if TYPE_CHECKING:
    from parcover_env.config import MapConfig

__all__ = ["MapModel", "checked_polygon", "map_model"]


def checked_polygon(coords, key: str) -> Polygon:
    """A valid, non-degenerate shapely polygon, or a ConfigError naming ``key``."""
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

    def __getstate__(self) -> dict:
        """Copies and pickles carry the geometry only; the cached ``segments`` (read-only) and the
        prepared polygon are derived again on first use."""
        return {"free": self.free, "bounds": self.bounds}

    @classmethod
    def from_config(cls, cfg: MapConfig, include_unknown: bool = True) -> MapModel:
        """Build the map; ``include_unknown`` adds the obstacles missing from the known map."""
        floor = checked_polygon(cfg.boundary, "map.boundary") if cfg.boundary else box(0, 0, *cfg.size)
        solids = [checked_polygon(p, f"map.obstacles[{i}]") for i, p in enumerate(cfg.obstacles)]
        half = cfg.wall_thickness / 2
        solids += [LineString(w).buffer(half, cap_style="square", join_style="mitre") for w in cfg.walls]
        if include_unknown:
            solids += [checked_polygon(p, f"map.unknown_obstacles[{i}]") for i, p in enumerate(cfg.unknown_obstacles)]
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
        segments = np.concatenate([polygon_edges(r) for r in rings]).astype(float)
        segments.setflags(write=False)  # shared by every sensor; they key caches on it
        return segments

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


def map_model(cfg: MapConfig, include_unknown: bool = True) -> MapModel:
    """The map of ``cfg``, built once per process and shared (maps are immutable)."""
    return _cached_map_model(cfg, bool(include_unknown))


@lru_cache(maxsize=64)
def _cached_map_model(cfg: MapConfig, include_unknown: bool) -> MapModel:
    return MapModel.from_config(cfg, include_unknown)
