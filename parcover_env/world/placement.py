"""Initial placement of the team around the start pose."""

from __future__ import annotations

import math

import numpy as np

from parcover_env.errors import ConfigError
from parcover_env.world.map_model import MapModel

__all__ = ["start_poses"]


def start_poses(map_model: MapModel, start: tuple[float, float, float], n: int, radius: float,
                spacing: float, source: str = "") -> np.ndarray:
    """Poses ``(n, 3)``: robot 0 on the start, the others packed behind it, column first.

    Candidates lie on a lattice aligned with the start heading (pitch ``max(spacing, 2.6 r)``
    along, ``2.6 r`` across); they are taken in order of distance behind the start, lateral
    offsets costing twice as much, so a narrow corridor yields a column and a wide one a block.
    All robots face the start heading. Raises ConfigError if the team does not fit.
    """
    x0, y0, th = start
    along = max(spacing, 2.6 * radius)
    across = 2.6 * radius
    n_rows = n + 1
    half = max(1, math.ceil(n / 2))
    rows, cols = np.meshgrid(np.arange(n_rows), np.arange(-half, half + 1), indexing="ij")
    back = rows.ravel() * along
    lat = cols.ravel() * across
    cost = back + 2.0 * np.abs(lat) + 1e-6 * lat  # tiny tie-break: right before left, deterministic
    order = np.argsort(cost, kind="stable")
    c, s = math.cos(th), math.sin(th)
    pts = np.stack([x0 - back * c - lat * s, y0 - back * s + lat * c], axis=1)[order]
    ok = map_model.contains(pts, margin=radius * 1.05)
    region = map_model.reachable_region((x0, y0), radius)
    chosen: list[np.ndarray] = []
    for p, good in zip(pts, ok):
        if not good or region is None or not region.buffer(1e-6).contains(_point(p)):
            continue
        if all(np.hypot(*(p - q)) >= 2.2 * radius for q in chosen):
            chosen.append(p)
        if len(chosen) == n:
            break
    if len(chosen) < n:
        raise ConfigError(source, "n_robots", f"only {len(chosen)} of {n} robots fit around the start "
                          "without touching walls; move the start or use fewer robots")
    out = np.empty((n, 3))
    out[:, :2] = chosen
    out[:, 2] = th
    return out


def _point(p):
    from shapely.geometry import Point

    return Point(float(p[0]), float(p[1]))
