"""Keeping clear of walls and teammates: pure functions shared by the expert's controllers."""

from __future__ import annotations

import math

import numpy as np

from parcover_env.geometry import wrap_angle

__all__ = ["brake_factor", "lane_gap", "sidestep", "turn_away"]


def brake_factor(distance: float, stop: float, slow: float) -> float:
    """Speed factor for an obstacle ``distance`` away: 0 at or below ``stop``, 1 at or beyond
    ``slow``, linear in between (m)."""
    return float(np.clip((distance - stop) / (slow - stop), 0.0, 1.0))


def lane_gap(xy: np.ndarray, i: int, heading: float, lane: float, diameter: float) -> tuple[float, int]:
    """``(gap, j)``: free distance between robot ``i`` and the nearest robot ``j`` in the lane ``i``
    sweeps driving straight along ``heading`` (in front, and closer to the heading line than
    ``lane``), for robots of ``diameter`` at positions ``xy`` ``(N, 2)``; ``(inf, -1)`` if none."""
    d = xy - xy[i]
    c, s = math.cos(heading), math.sin(heading)
    ahead = ((d[:, 0] * c + d[:, 1] * s) > 0) & (np.abs(d[:, 1] * c - d[:, 0] * s) < lane)
    ahead[i] = False
    if not ahead.any():
        return math.inf, -1
    dist = np.where(ahead, np.hypot(d[:, 0], d[:, 1]), np.inf)
    j = int(np.argmin(dist))
    return float(dist[j]) - diameter, j


def sidestep(xy_i: np.ndarray, xy_j: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``d`` turned perpendicular to the line from ``xy_i`` to ``xy_j`` (same length), on the side
    nearer to ``d``: the way past a robot at ``xy_j`` that blocks ``d`` and will not move."""
    rel = xy_j - xy_i
    phi, want = math.atan2(rel[1], rel[0]), math.atan2(d[1], d[0])
    side = min((phi + math.pi / 2, phi - math.pi / 2), key=lambda a: abs(wrap_angle(a - want)))
    return math.hypot(d[0], d[1]) * np.array([math.cos(side), math.sin(side)])


def turn_away(ranges: np.ndarray, angles: np.ndarray, stop: float, slow: float, w_max: float) -> float:
    """Turn rate (rad/s) away from the nearest of the echoes ``ranges`` (m) at beam ``angles`` (rad,
    robot frame): 0 beyond ``slow``, rising linearly to ``w_max`` at ``stop``; 0 without beams."""
    if len(ranges) == 0:
        return 0.0
    k = int(np.argmin(ranges))
    push = float(np.clip((slow - float(ranges[k])) / (slow - stop), 0.0, 1.0))
    return -math.copysign(push * w_max, float(wrap_angle(angles[k])))
