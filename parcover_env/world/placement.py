"""Initial placement of the team around the start pose."""

from __future__ import annotations

import math

import numpy as np
import shapely

from parcover_env.errors import ConfigError
from parcover_env.geometry import atan2
from parcover_env.world.map_model import MapModel

__all__ = ["start_poses", "queue_poses"]


def queue_poses(map_model: MapModel, queue, n: int, radius: float, spacing: float,
                source: str = "") -> np.ndarray:
    """Poses ``(n, 3)`` every ``spacing`` metres along the polyline ``queue`` (start first), each
    robot facing the one ahead of it (robot 0 faces along the first segment, reversed)."""
    pts = np.asarray(queue, dtype=float)
    seg = np.diff(pts, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    s = np.arange(n) * spacing
    if s[-1] > cum[-1] + 1e-9:
        raise ConfigError(source, "start_queue", f"the queue is {cum[-1]:.2f} m long; {n} robots "
                          f"{spacing} m apart need {s[-1]:.2f} m")
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    u = (s - cum[k]) / np.where(seg_len[k] > 0, seg_len[k], 1.0)
    xy = pts[k] + u[:, None] * seg[k]
    heading = atan2(-seg[k, 1], -seg[k, 0])  # facing back up the queue, toward the start
    ok = map_model.contains(xy, margin=radius)
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        raise ConfigError(source, "start_queue", f"robot {i}'s place {xy[i].round(3).tolist()} is in or "
                          f"within {radius} m of a wall")
    return np.column_stack([xy, heading])


def start_poses(map_model: MapModel, start: tuple[float, float, float], n: int, radius: float,
                spacing: float, source: str = "") -> np.ndarray:
    """Poses ``(n, 3)``: robot 0 on the start, the others packed behind it, column first.

    Candidates lie on a lattice aligned with the start heading (pitch ``max(spacing, 2.6 r)``
    along, ``2.6 r`` across); they are taken in order of distance behind the start, lateral
    offsets costing twice as much, so a narrow corridor yields a column and a wide one a block.
    All robots face the start heading. The lattice spans ``n + 1`` rows and ``n`` columns on each
    side, so a team that fits is never refused because the lattice was too small (a larger ``n``
    must not seat more robots than a smaller one). Raises ConfigError if the team does not fit.
    """
    x0, y0, th = start
    along = max(spacing, 2.6 * radius)
    across = 2.6 * radius
    n_rows = n + 1
    half = max(1, n)
    rows, cols = np.meshgrid(np.arange(n_rows), np.arange(-half, half + 1), indexing="ij")
    back = rows.ravel() * along
    lat = cols.ravel() * across
    cost = back + 2.0 * np.abs(lat) + 1e-6 * lat  # tiny tie-break: right before left, deterministic
    order = np.argsort(cost, kind="stable")
    c, s = math.cos(th), math.sin(th)
    pts = np.stack([x0 - back * c - lat * s, y0 - back * s + lat * c], axis=1)[order]
    ok = map_model.contains(pts, margin=radius * 1.05)
    region = map_model.reachable_region((x0, y0), radius)
    if region is not None:  # one vectorized test (buffering per candidate was O(lattice) slow)
        grown = region.buffer(1e-6)
        shapely.prepare(grown)
        ok &= shapely.contains_xy(grown, pts[:, 0], pts[:, 1])
    chosen: list[np.ndarray] = []
    for p, good in zip(pts, ok, strict=True):
        if not good or region is None:
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
