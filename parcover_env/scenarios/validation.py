"""Geometric checks of a scenario against its map: what the schema alone cannot see."""

from __future__ import annotations

import shapely
from shapely.geometry import Point, box

from parcover_env.config import Scenario
from parcover_env.errors import ConfigError
from parcover_env.geometry.camera import CameraModel
from parcover_env.world.map_model import MapModel, checked_polygon, map_model

__all__ = ["validate_geometry", "kinect_blind_spots"]


def validate_geometry(s: Scenario, world: MapModel | None = None, known: MapModel | None = None) -> None:
    """Raise ConfigError naming the offending key; ``world``/``known`` reuse already built maps."""
    cfg = s.map
    if cfg.boundary:
        checked_polygon(cfg.boundary, "map.boundary")
    world = world or map_model(cfg, include_unknown=True)
    known = known or map_model(cfg, include_unknown=False)
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
        footprint = CameraModel.from_config(kin).footprint()
        if footprint.is_empty or not footprint.intersects(box(*world.bounds)):
            raise ConfigError("", f"kinects[{i}]", f"Kinect '{kin.name}' does not see the map's floor")
    if s.kinects and s.localization == "kinect":
        blind = kinect_blind_spots(s)
        if blind:
            key, xy = blind[0]
            raise ConfigError("", key, f"{tuple(round(v, 3) for v in xy)} is seen by no Kinect (a robot there is not "
                              f"wholly inside any footprint at marker height {s.robot.height} m); with "
                              "'localization: kinect' every start, TP and KPOI must be in view (Alg. 1) — move or "
                              "add a Kinect, or use 'localization: both' (sonar where no Kinect sees)")


def kinect_blind_spots(s: Scenario) -> list[tuple[str, tuple[float, float]]]:
    """The start, turning positions and KPOIs of ``s`` no Kinect sees, as ``(key, (x, y))``.

    Seen = a robot centred there lies wholly inside some Kinect's footprint at the height of its
    markers (``robot.height``), so the marker pipeline can detect it. Min et al. (Alg. 1, Fig. 11):
    the Kinect system detects leaders at the start, at each TP (to split the group) and at the KPOIs.
    TPs come from the scenario's PPCP plan (cached, shared with the env).
    """
    from parcover_env.planning import plan_scenario

    seen = shapely.union_all([CameraModel.from_config(k).footprint(s.robot.height) for k in s.kinects])
    seen = seen.buffer(-s.robot.radius)
    shapely.prepare(seen)
    points = [("start", (s.start.x, s.start.y))]
    points += [(f"turning_positions[{i}]", tp.position)
               for i, tp in enumerate(plan_scenario(s, s.n_robots_fixed).turning_points)]
    points += [(f"kpois[{i}]", tuple(k)) for i, k in enumerate(s.kpois)]
    return [(key, (float(x), float(y))) for key, (x, y) in points if not seen.contains(Point(x, y))]
