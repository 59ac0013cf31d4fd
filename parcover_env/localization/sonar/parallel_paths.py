"""Parallel paths for a team (Kim, Pearce & Amato §2 and §4): replicate the path and translate it.

"From the path, multiple paths are computed by replicating and translating segments." Robot i's
lane is its route translated sideways by its lane offset ``o_i`` (:func:`lane_offsets`): every
segment moves by ``o_i`` along its left normal and consecutive translated segments meet at their
mitre point (:func:`node_normals`). Where the corridor is too narrow the lane merges back onto the
route: a lane node is *allowed* when the translated point keeps ``clearance`` from every wall of the
known map and the sideways segment from the route to it crosses none (:func:`lane_allowed`). The
sideways shift is ``a o_i`` with a weight ``a`` in [0, 1]: 0 at every node not allowed and at both
ends of the route (a robot starts and ends on its route), rising linearly with the arclength
distance from them over ``ramp`` metres (:func:`lane_weights`). Translated nodes of the inner side of
a turn that overshoot the mitre point lie closer to the route than their shift; they are dropped
(the usual trimming of an offset curve).

Arclength labels: a lane node keeps the arclength of its route node, so the team's common label
``sigma`` puts all robots abreast. Where the lanes merge, robots would meet on the route, so robot
i falls back ``lag_i`` behind: its label there is ``s - (1 - b) lag_i`` with ``b`` the weight of the
narrow parts alone (not of the route's ends). Labels stay increasing when ``ramp > lag_i``.
"""

from __future__ import annotations

import numpy as np
import shapely

from parcover_env.localization.sonar.subgoals import PathNodes, densify

__all__ = ["lane_offsets", "node_normals", "lane_allowed", "lane_weights", "parallel_path", "with_start",
           "lateral_offset"]

MAX_MITRE = 2.0
"""Largest mitre factor at a vertex (a turn of 120 deg): sharper turns cut the corner."""


def lane_offsets(n: int, spacing: float) -> np.ndarray:
    """``(n,)`` sideways offsets (m, + = left of travel) of ``n`` lanes ``spacing`` apart, centred on
    the route, robot 0 leftmost."""
    return ((n - 1) / 2 - np.arange(n)) * float(spacing)


def node_normals(xy: np.ndarray) -> np.ndarray:
    """``(P, 2)`` left normals of a polyline's nodes, scaled so that ``xy + o * normal`` is the
    polyline with every segment translated by ``o`` (a node between two segments: the mitre point
    where the translated segments meet, factor capped at ``MAX_MITRE``)."""
    p = np.asarray(xy, dtype=float)
    if len(p) < 2:
        return np.zeros_like(p)
    d = np.diff(p, axis=0)
    u = d / np.maximum(np.hypot(*d.T), 1e-12)[:, None]
    before = np.vstack([u[:1], u])   # direction of the segment ending at each node
    after = np.vstack([u, u[-1:]])   # ... and of the one starting there
    t = before + after
    t /= np.maximum(np.hypot(*t.T), 1e-12)[:, None]
    n = np.stack([-t[:, 1], t[:, 0]], axis=1)
    cos_half = np.einsum("ij,ij->i", n, np.stack([-before[:, 1], before[:, 0]], axis=1))
    return n / np.maximum(cos_half, 1.0 / MAX_MITRE)[:, None]


def lane_allowed(route: PathNodes, offset: float, map_model, clearance: float) -> np.ndarray:
    """``(P,)`` bool: the route's nodes translated by ``offset`` (m) keep ``clearance`` (m) from the
    known map's walls, and the sideways segments from the route to them cross no wall."""
    lane = route.xy + offset * node_normals(route.xy)
    ok = map_model.contains(lane, margin=clearance)
    segs = shapely.linestrings(np.stack([route.xy, lane], axis=1))
    return ok & shapely.covers(map_model.free, segs)


def lane_weights(s: np.ndarray, blocked: np.ndarray, ramp: float, taper_ends: bool = True) -> np.ndarray:
    """``(P,)`` weight in [0, 1] of the lane's shift at arclengths ``s``: the arclength distance to the
    nearest ``blocked`` node (and, with ``taper_ends``, to the route's first and last node) over
    ``ramp`` (m), capped at 1."""
    s = np.asarray(s, dtype=float)
    dist = np.full(len(s), np.inf)
    if np.any(blocked):
        dist = np.min(np.abs(s[:, None] - s[np.asarray(blocked, dtype=bool)][None, :]), axis=1)
    if taper_ends:
        dist = np.minimum(dist, np.minimum(s - s[0], s[-1] - s))
    return np.clip(dist / ramp, 0.0, 1.0)


def parallel_path(route: PathNodes, offset: float, map_model, clearance: float, ramp: float,
                  lag: float = 0.0) -> PathNodes:
    """Robot's lane: ``route`` translated by ``offset`` (m) where ``clearance`` allows, merged onto it
    elsewhere, with the team's arclength labels (``lag`` m behind where merged). See the module
    docstring."""
    if not ramp > 0:
        raise ValueError(f"ramp must be > 0, got {ramp}")
    if lag >= ramp:
        raise ValueError(f"lag ({lag} m) must be < ramp ({ramp} m): labels must increase")
    if offset == 0.0 or len(route.xy) < 2:
        return route
    blocked = ~lane_allowed(route, offset, map_model, clearance)
    a = lane_weights(route.s, blocked, ramp)
    b = lane_weights(route.s, blocked, ramp, taper_ends=False)
    lane = route.xy + (a * offset)[:, None] * node_normals(route.xy)
    line = shapely.LineString(route.xy)
    keep = shapely.distance(line, shapely.points(lane)) >= np.abs(a * offset) * (1 - 1e-6) - 1e-9
    keep[[0, -1]] = True
    return PathNodes(lane[keep], (route.s - (1.0 - b) * lag)[keep])


def with_start(path: PathNodes, start: np.ndarray, step: float) -> PathNodes:
    """``path`` preceded by the straight way from ``start`` to its first node (labels before its first)."""
    lead = float(np.hypot(*(np.asarray(start, dtype=float) - path.xy[0])))
    if lead <= 1e-3:
        return path
    head = densify(np.vstack([start, path.xy[0]]), step, s0=float(path.s[0]) - lead)
    return PathNodes(np.vstack([head.xy[:-1], path.xy]), np.concatenate([head.s[:-1], path.s]))


def lateral_offset(xy: np.ndarray, heading: np.ndarray) -> float:
    """Distance (m) between two robots at ``xy (2, 2)`` across their mean heading (``heading (2,)``, rad)."""
    h = np.arctan2(np.sin(heading).sum(), np.cos(heading).sum())
    d = np.asarray(xy[1], dtype=float) - np.asarray(xy[0], dtype=float)
    return float(abs(-np.sin(h) * d[0] + np.cos(h) * d[1]))
