"""Map features (concave corners) and characteristic points of a 360-degree sonar scan (Kim, Pearce & Amato §2.1).

Characteristic points, one letter per reading: ``m`` local minimum (foot of a wall's perpendicular),
``M`` local maximum (a concave corner: the paper's *feature*), ``D``/``c`` the far/near side of a
range jump above ``jump_threshold`` (``c`` is a convex corner), ``f`` too far / no echo, ``.`` none.
Priority when several apply: f > M > D/c > m (a concave corner seen at a grazing angle can
show range steps above the jump threshold next to it; it stays a feature).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient

from parcover_env.localization.sonar import scan_kernels
from parcover_env.localization.sonar.params import SonarLocalizerParams

__all__ = ["MapFeature", "map_features", "ScanPoints", "WallObservation", "CornerObservation",
           "characteristic_points"]


@dataclass(frozen=True, eq=False)
class MapFeature:
    """A concave corner of the free space: two walls meeting at < 180 deg, facing the robot."""

    index: int
    point: np.ndarray
    """Corner position (2,)."""
    walls: np.ndarray
    """(2, 2) unit directions along the two adjacent walls, leaving the corner."""
    normals: np.ndarray
    """(2, 2) unit normals of the two walls, pointing into free space."""
    lengths: np.ndarray
    """(2,) lengths of the two adjacent walls (m)."""


def map_features(map_model, min_turn_deg: float = 1.0) -> list[MapFeature]:
    """Concave corners of ``map_model.free`` (convex vertices of the free-space polygon), in ring
    order (exterior first, then holes)."""
    polys = list(getattr(map_model.free, "geoms", [map_model.free]))
    feats: list[MapFeature] = []
    sin_min = np.sin(np.radians(min_turn_deg))
    for poly in polys:
        poly = orient(Polygon(poly), 1.0)  # free space on the left of every edge
        for ring in [poly.exterior, *poly.interiors]:
            pts = np.asarray(ring.coords, dtype=float)[:-1]
            prev, nxt = np.roll(pts, 1, axis=0), np.roll(pts, -1, axis=0)
            e_in, e_out = pts - prev, nxt - pts
            l_in, l_out = np.linalg.norm(e_in, axis=1), np.linalg.norm(e_out, axis=1)
            ok = (l_in > 1e-9) & (l_out > 1e-9)
            cross = (e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0]) / np.maximum(l_in * l_out, 1e-18)
            for i in np.nonzero(ok & (cross > sin_min))[0]:
                u1, u2 = -e_in[i] / l_in[i], e_out[i] / l_out[i]
                walls = np.stack([u1, u2])
                # free side of each wall: towards the other wall, perpendicular to it
                n1 = u2 - (u2 @ u1) * u1
                n2 = u1 - (u1 @ u2) * u2
                normals = np.stack([n1 / np.linalg.norm(n1), n2 / np.linalg.norm(n2)])
                feats.append(MapFeature(len(feats), pts[i].copy(), walls, normals,
                                        np.array([l_in[i], l_out[i]])))
    return feats


@dataclass(frozen=True)
class WallObservation:
    """A wall seen in the scan (robot frame): unit normal bearing towards the wall and distance."""

    bearing: float
    distance: float
    index: int


@dataclass(frozen=True)
class CornerObservation:
    """A candidate concave corner in the scan (robot frame): bearing and range of an M point."""

    bearing: float
    range: float
    index: int


@dataclass(frozen=True, eq=False)
class ScanPoints:
    labels: str
    """One letter per reading (see module docstring)."""
    maxima: np.ndarray
    """Indices of M points."""
    minima: np.ndarray
    """Indices of m points."""
    corners: list[CornerObservation]
    """Corner candidates: M points plus maxima bounded by f (plateau-centre bearings)."""
    walls: list[WallObservation]
    """One wall per m point (normal bearing from a line fit or the plateau centre)."""


def characteristic_points(ranges, angles, range_max: float,
                          params: SonarLocalizerParams | None = None) -> ScanPoints:
    """Characteristic points of a circular scan ``ranges (n,)`` taken at robot-frame ``angles (n,)``.

    ``maxima`` (the M labels) need echoes on both sides. ``corners`` (candidates for the localizer)
    also take maxima next to an f: a specular sonar sees a corner as a run of echoes between f's.
    For minima f counts as higher than any echo.
    """
    p = params or SonarLocalizerParams()
    r = np.asarray(ranges, dtype=float)
    a = np.asarray(angles, dtype=float)
    if r.ndim != 1 or a.shape != r.shape or len(r) < 3:
        raise ValueError(f"ranges and angles must be equal-length 1-D arrays (>= 3), got {r.shape}, "
                         f"{a.shape}")
    if not np.all(np.isfinite(r)):
        raise ValueError("ranges contain NaN or infinite values")
    labels, corners, walls = scan_kernels.characteristic_points(
        np.ascontiguousarray(r), *_sin_cos(a), float(range_max), float(p.far_margin), float(p.jump_threshold),
        float(p.prominence), int(p.window), float(p.plateau_tol), float(p.line_tol), _OFF_NORMAL)
    return ScanPoints("".join([scan_kernels.LABEL_CODES[c] for c in labels.tolist()]), np.flatnonzero(labels == 4),
                      np.flatnonzero(labels == 1),
                      [CornerObservation(b, rr, int(i)) for b, rr, i in corners.tolist()],
                      [WallObservation(b, d, int(i)) for b, d, i in walls.tolist()])


_OFF_NORMAL = float(np.radians(20.0))
"""A wall's fitted normal replaces its plateau bearing when within this of it (rad)."""


def _sin_cos(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """numpy's sines and cosines of the reading angles ``a`` (contiguous), for the compiled scan kernels."""
    return np.ascontiguousarray(np.sin(a)), np.ascontiguousarray(np.cos(a))
