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

from parcover_env.geometry import atan2, wrap_angle
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


def _side_windows(n: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    i = np.arange(n)[:, None]
    k = np.arange(1, w + 1)[None, :]
    return (i - k) % n, (i + k) % n


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
    n = len(r)
    far = r >= range_max - p.far_margin
    nxt = np.roll(np.arange(n), -1)
    jump = ~far & ~far[nxt] & (np.abs(r - r[nxt]) > p.jump_threshold)
    is_d = np.zeros(n, bool)
    is_c = np.zeros(n, bool)
    for i in np.nonzero(jump)[0]:
        j = nxt[i]
        hi, lo = (i, j) if r[i] > r[j] else (j, i)
        is_d[hi] = True
        is_c[lo] = True
    w = min(p.window, (n - 1) // 2)
    left, right = _side_windows(n, w)
    rl, rr = r[left], r[right]
    fl, fr = far[left], far[right]
    # maxima: f neighbours count as lower (unknown), echoes must not exceed r_i
    lmax = np.where(fl, -np.inf, rl).max(axis=1)
    rmax = np.where(fr, -np.inf, rr).max(axis=1)
    lmin = np.where(fl, -np.inf, rl).min(axis=1, initial=np.inf)
    rmin = np.where(fr, -np.inf, rr).min(axis=1, initial=np.inf)
    prom_l = fl.any(axis=1) | (r - np.where(np.isfinite(lmin), lmin, r) >= p.prominence)
    prom_r = fr.any(axis=1) | (r - np.where(np.isfinite(rmin), rmin, r) >= p.prominence)
    loose_max = ~far & ~is_c & (r > lmax) & (r >= rmax) & prom_l & prom_r
    # an M point proper has echoes (not f) on both sides: a wall reaching the range limit is no corner
    is_max = loose_max & ~fl[:, 0] & ~fr[:, 0]
    # minima: f neighbours count as higher
    lmn = np.where(fl, np.inf, rl).min(axis=1)
    rmn = np.where(fr, np.inf, rr).min(axis=1)
    is_min = ~far & ~is_d & ~is_c & (r < lmn) & (r <= rmn)
    labels = np.full(n, ".")
    labels[is_min] = "m"
    labels[is_c] = "c"
    labels[is_d] = "D"
    labels[is_max] = "M"
    labels[far] = "f"
    maxima, minima = np.nonzero(is_max)[0], np.nonzero(is_min)[0]
    corners = [CornerObservation(_plateau_bearing(r, a, far, i, p.plateau_tol), float(r[i]), int(i))
               for i in np.nonzero(loose_max)[0]]
    walls = [_wall_observation(r, a, far, i, p) for i in minima]
    return ScanPoints("".join(labels), maxima, minima, corners, walls)


def _plateau(r, far, i, tol) -> list[int]:
    """Contiguous readings (circular) within ``tol`` of reading ``i``, in angular order."""
    n = len(r)
    run = [i]
    for step in (-1, 1):
        j = i
        for _ in range(n // 2):
            j = (j + step) % n
            if far[j] or abs(r[j] - r[i]) > tol or j in run:
                break
            run.insert(0, j) if step < 0 else run.append(j)
    return run


def _circular_mean(angles) -> float:
    return float(atan2(np.mean(np.sin(angles)), np.mean(np.cos(angles))))


def _plateau_bearing(r, a, far, i, tol) -> float:
    return _circular_mean(a[_plateau(r, far, i, tol)])


def _wall_observation(r, a, far, i, p: SonarLocalizerParams) -> WallObservation:
    run = _plateau(r, far, i, p.plateau_tol)
    n = len(r)
    idx = [(run[0] - k) % n for k in range(p.window, 0, -1)] + run + [(run[-1] + k) % n
                                                                    for k in range(1, p.window + 1)]
    idx = [j for j in dict.fromkeys(idx) if not far[j]]
    bearing = _circular_mean(a[run])
    if len(idx) >= 3:
        pts = np.stack([r[idx] * np.cos(a[idx]), r[idx] * np.sin(a[idx])], axis=1)
        centre = pts.mean(axis=0)
        _, s, vt = np.linalg.svd(pts - centre)
        normal = vt[1]
        if normal @ centre < 0:
            normal = -normal
        rms = s[1] / np.sqrt(len(idx))
        if rms < p.line_tol and abs(wrap_angle(atan2(normal[1], normal[0]) - bearing)) \
                < np.radians(20.0):
            bearing = float(atan2(normal[1], normal[0]))
    return WallObservation(bearing, float(r[i]), int(i))
