"""Reference of :mod:`parcover_env.localization.sonar` before it was compiled (issue 40): the localizer
(Kim, Pearce & Amato Fig. 6 and our extensions), the characteristic points of a scan and the Fig. 11
filter as plain Python, numpy, shapely and scipy, kept verbatim from the code the pinned scans
(``tests/localization/sonar/pinned_scans.json``) were written with. The compiled localizer must give
the same results (``tests/localization/sonar/test_localizer_kernels.py``); ``benchmarks/sonar_localization.py
--reference`` times this one next to it.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from scipy.optimize import minimize

from parcover_env.config import SonarConfig
from parcover_env.geometry import atan2, wrap_angle
from parcover_env.localization.sonar.features import (
    CornerObservation,
    MapFeature,
    ScanPoints,
    WallObservation,
    map_features,
)
from parcover_env.localization.sonar.localizer import Ellipse, LocalizationResult
from parcover_env.localization.sonar.params import SonarLocalizerParams
from parcover_env.localization.sonar.sectors import Sector
from parcover_env.sensors.sonar import simulate_beams


def ellipse_distance(self, points) -> np.ndarray:
    """Distance from each point ``(P, 2)`` to the ellipse (0 inside); boundary sampled at 256 points."""
    p = np.atleast_2d(np.asarray(points, dtype=float)) - np.asarray(self.center)
    c, s = math.cos(self.angle), math.sin(self.angle)
    local = np.stack([c * p[:, 0] + s * p[:, 1], -s * p[:, 0] + c * p[:, 1]], axis=1)
    a, b = max(self.axes[0], 1e-9), max(self.axes[1], 1e-9)
    inside = (local[:, 0] / a) ** 2 + (local[:, 1] / b) ** 2 <= 1.0
    t = np.linspace(0, 2 * math.pi, 256, endpoint=False)
    edge = np.stack([a * np.cos(t), b * np.sin(t)], axis=1)
    d = np.linalg.norm(local[:, None, :] - edge[None, :, :], axis=-1).min(axis=1)
    return np.where(inside, 0.0, d)


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


def _fit_line(pts: np.ndarray) -> tuple[np.ndarray, float, float]:
    centre = pts.mean(axis=0)
    _, s, vt = np.linalg.svd(pts - centre)
    normal = vt[1]
    if normal @ centre < 0:
        normal = -normal
    return normal, float(normal @ centre), float(s[1] / np.sqrt(len(pts)))


def filter_scan(ranges, angles, range_max: float, repeats: int = 4, half_window: int = 1,
                line_tol: float = 0.03) -> np.ndarray:
    """Filtered copy of a circular scan ``ranges (n,)`` at robot-frame ``angles (n,)`` (Fig. 11)."""
    r = np.array(ranges, dtype=float)
    a = np.asarray(angles, dtype=float)
    if r.ndim != 1 or r.shape != a.shape or len(r) < 2 * half_window + 3:
        raise ValueError(f"ranges and angles must be equal-length 1-D arrays, got {r.shape}, {a.shape}")
    if repeats < 1 or half_window < 1:
        raise ValueError(f"repeats and half_window must be >= 1, got {repeats}, {half_window}")
    n = len(r)
    done = np.zeros(n, dtype=bool)
    u = np.stack([np.cos(a), np.sin(a)], axis=1)
    for _ in range(repeats):
        free = np.nonzero(~done & (r < range_max))[0]
        if len(free) == 0:
            break
        ms = int(free[np.argmin(r[free])])
        done[ms] = True
        idx = [(ms + k) % n for k in range(-half_window, half_window + 1)]
        if np.any(r[idx] >= range_max):
            continue
        normal, dist, rms = _fit_line(r[idx, None] * u[idx])
        if rms > line_tol:
            continue
        for step in (-1, 1):
            cur = ms
            for _ in range(n - 1):
                nxt = (cur + step) % n
                if nxt == ms or r[nxt] <= r[cur]:
                    break
                cos = float(u[nxt] @ normal)
                if cos <= 0.05 or dist / cos > range_max or dist / cos > r[nxt] + line_tol:
                    break  # L runs behind the reading: a nearer surface (the next wall of a corner)
                r[nxt] = dist / cos
                done[nxt] = True
                cur = nxt
    return r


def synthetic_scans(poses, scan_angles, segments, sonar: SonarConfig) -> np.ndarray:
    """Noise-free scans ``(H, n)`` of the map from each pose ``(H, 3)``."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    axes = poses[:, 2:3] + np.asarray(scan_angles, dtype=float)[None, :]
    return simulate_beams(sonar, poses[:, :2], axes, segments, np.zeros((0, 2)), 0.0,
                          np.full(len(poses), -1))


def scan_error(measured, synthetic, clip: float, trim: float = 0.0) -> np.ndarray:
    """Mean clipped absolute range error per synthetic scan (rows), over the best ``1 - trim``
    share of the readings (``trim`` drops the worst: other robots, multipath, unknown obstacles)."""
    e = np.minimum(np.abs(np.atleast_2d(synthetic) - np.asarray(measured)[None, :]), clip)
    keep = e.shape[1] - int(math.floor(trim * e.shape[1]))
    if keep < e.shape[1]:
        e = np.partition(e, keep - 1, axis=1)[:, :keep]
    return e.mean(axis=1)


def pose_candidates(feature: MapFeature, scan: ScanPoints, params: SonarLocalizerParams) -> list[np.ndarray]:
    """Poses (x, y, theta) that explain ``feature`` by the scan's walls and corners."""
    c, out = feature.point, []
    tol = math.radians(params.heading_tol_deg)
    normal_ang = [math.atan2(-n[1], -n[0]) for n in feature.normals]  # robot -> wall direction
    heads = [[(float(wrap_angle(normal_ang[i] - w.bearing)), w) for w in scan.walls] for i in (0, 1)]
    for th0, w0 in heads[0]:
        for th1, w1 in heads[1]:
            if w0.index == w1.index or abs(wrap_angle(th0 - th1)) > tol:
                continue
            th = math.atan2(math.sin(th0) + math.sin(th1), math.cos(th0) + math.cos(th1))
            try:
                p = c + np.linalg.solve(feature.normals, np.array([w0.distance, w1.distance]))
            except np.linalg.LinAlgError:
                continue
            out.append(np.array([p[0], p[1], th]))
    for i in (0, 1):
        n = feature.normals[i]
        for th, w in heads[i]:
            for k in scan.corners:
                p = c - k.range * np.array([math.cos(th + k.bearing), math.sin(th + k.bearing)])
                if abs(n @ (p - c) - w.distance) <= 2 * params.line_tol + 0.02 * w.distance:
                    out.append(np.array([p[0], p[1], th]))
    return out


def arc_candidates(feature: MapFeature, scan: ScanPoints, region: shapely.Geometry,
                   step: float = 0.03) -> list[np.ndarray]:
    """Fallback beyond the paper (``arc_fallback``) when no wall of the corner shows its perpendicular
    foot: poses on the circle of the measured corner range around the corner, inside the corner's
    wedge and ``region`` (the grown ellipse), every ``step`` metres of arc; heading from the corner's
    measured bearing."""
    c, out = feature.point, []
    a1 = math.atan2(feature.walls[0][1], feature.walls[0][0])
    span = float(wrap_angle(math.atan2(feature.walls[1][1], feature.walls[1][0]) - a1))
    for k in scan.corners:
        n = max(2, int(abs(span) * k.range / step))
        psi = a1 + np.linspace(0.0, span, n + 1)[1:-1]
        pts = c + k.range * np.stack([np.cos(psi), np.sin(psi)], axis=1)
        inside = shapely.contains_xy(region, pts[:, 0], pts[:, 1])
        for q, ps in zip(pts[inside], psi[inside], strict=True):
            out.append(np.array([q[0], q[1], float(wrap_angle(ps + math.pi - k.bearing))]))
    return out


def _grid_candidates(ellipse: Ellipse, heading: float, map_model, p: SonarLocalizerParams) -> np.ndarray:
    """Grid fallback beyond the paper (``grid_fallback``): poses every ``grid_step`` m inside the
    uncertainty ellipse and in free space, at the heading estimate and ``grid_heading_step_deg``
    either side of it."""
    c, s = math.cos(ellipse.angle), math.sin(ellipse.angle)
    a, b = max(ellipse.axes[0], p.grid_step), max(ellipse.axes[1], p.grid_step)
    u, v = np.meshgrid(np.arange(-a, a + 1e-9, p.grid_step), np.arange(-b, b + 1e-9, p.grid_step))
    inside = (u / a) ** 2 + (v / b) ** 2 <= 1.0
    u, v = u[inside], v[inside]
    xy = np.stack([ellipse.center[0] + c * u - s * v, ellipse.center[1] + s * u + c * v], axis=1)
    xy = xy[map_model.contains(xy)]
    dh = math.radians(p.grid_heading_step_deg)
    heads = heading + dh * np.arange(-p.grid_heading_steps, p.grid_heading_steps + 1)
    return np.column_stack([np.repeat(xy, len(heads), axis=0), np.tile(heads, len(xy))])


def localize(scan_ranges, scan_angles, map_model, sectors: list[Sector],
             ellipse: Ellipse | tuple[np.ndarray, np.ndarray],
             params: SonarLocalizerParams | None = None, *, sonar: SonarConfig | None = None,
             features: list[MapFeature] | None = None, heading: float | None = None,
             heading_tol: float | None = None) -> LocalizationResult:
    """Localize from a 360-degree scan with the known map (Kim, Pearce & Amato Fig. 6, plus the
    extensions ``params`` switches on: see the module docstring). ``ellipse``: the
    uncertainty region, an :class:`Ellipse` or ``(center (2,), position covariance (2, 2))`` (e.g.
    propagated odometry), whose ``params.covariance_sigmas`` ellipse is used. ``sonar`` is the
    sensor model used for synthetic scans (default: ideal ray model); ``features`` as used for
    ``sectors``. ``heading``: the robot's heading estimate (rad, e.g. odometry); candidates farther
    than ``params.heading_prior_tol_deg`` from it are dropped (a symmetric corridor gives the same
    scan from a pose turned by 180 degrees). ``heading_tol`` (rad), if given, replaces that tolerance
    (e.g. a gate grown with the heading's standard deviation)."""
    p = params or SonarLocalizerParams()
    if isinstance(ellipse, tuple) and len(ellipse) == 2 and np.shape(ellipse[1]) == (2, 2):
        ellipse = Ellipse.from_covariance(ellipse[0], ellipse[1], p.covariance_sigmas)
    sonar = sonar or SonarConfig(model="ray")
    r = np.asarray(scan_ranges, dtype=float)
    a = np.asarray(scan_angles, dtype=float)
    if r.ndim != 1 or r.shape != a.shape:
        raise ValueError(f"scan_ranges and scan_angles must be 1-D of equal length, got {r.shape}, {a.shape}")
    if not isinstance(ellipse, Ellipse):
        raise ValueError(f"ellipse must be an Ellipse, got {type(ellipse).__name__}")
    if heading_tol is not None and not heading_tol > 0:
        raise ValueError(f"heading_tol must be > 0 (rad), got {heading_tol}")
    feats = map_features(map_model) if features is None else features
    region = ellipse.polygon().buffer(p.ellipse_distance)
    f1 = sorted(set().union(*[s.features for s in sectors if s.polygon.intersects(region)]))
    # Kim, Pearce & Amato Fig. 11: features also come from the filtered scan (too-long readings moved onto the
    # nearest walls); the raw scan's features stay candidates (the filter can erase a wall's end)
    scans = [characteristic_points(r, a, sonar.range_max, p)]
    if p.filter:
        r_filt = filter_scan(r, a, sonar.range_max, p.filter_repeats, p.filter_half_window, p.filter_line_tol)
        if not np.array_equal(r_filt, r):
            scans.insert(0, characteristic_points(r_filt, a, sonar.range_max, p))
    cands, owners = [], []
    for fi in f1:
        for scan in scans:
            qs = [q for q in pose_candidates(feats[fi], scan, p)
                  if ellipse_distance(ellipse, q[None, :2])[0] < p.ellipse_distance]
            if not qs and p.arc_fallback:
                qs = arc_candidates(feats[fi], scan, region)
            cands.extend(qs)
            owners.extend([fi] * len(qs))
    segs = map_model.segments
    poses = np.array(cands).reshape(-1, 3)
    keep = (ellipse_distance(ellipse, poses[:, :2]) < p.ellipse_distance) & map_model.contains(poses[:, :2])
    if heading is not None:
        tol = math.radians(p.heading_prior_tol_deg) if heading_tol is None else float(heading_tol)
        keep &= np.abs(wrap_angle(poses[:, 2] - float(heading))) <= tol
    poses, owners = poses[keep], np.asarray(owners, dtype=np.int64)[keep]
    _, uniq = np.unique(np.round(np.column_stack([poses[:, :2] / 0.01, poses[:, 2] / 0.01])), axis=0,
                        return_index=True)
    uniq = np.sort(uniq)[: p.max_candidates]
    poses, owners = poses[uniq], owners[uniq]
    err = scan_error(r, synthetic_scans(poses, a, segs, sonar), p.error_clip, p.error_trim) if len(poses) \
        else np.zeros(0)
    if heading is not None and p.grid_fallback and (len(err) == 0 or err.min() > p.success_error):
        # no feature pose explains the scan: scan matching over the uncertainty region instead
        grid = _grid_candidates(ellipse, float(heading), map_model, p)
        poses = np.concatenate([poses, grid])
        owners = np.concatenate([owners, np.full(len(grid), -1)])
        err = np.concatenate([err, scan_error(r, synthetic_scans(grid, a, segs, sonar), p.error_clip, p.error_trim)])
    if len(poses) == 0:
        return LocalizationResult(None, math.inf, 0, False)
    best = int(np.argmin(err))
    pose, e = poses[best].copy(), float(err[best])
    if p.polish:
        def cost(x):
            if not map_model.contains(x[None, :2])[0] or \
                    ellipse_distance(ellipse, x[None, :2])[0] >= p.ellipse_distance:
                return p.error_clip
            return float(scan_error(r, synthetic_scans(x[None], a, segs, sonar), p.error_clip, p.error_trim)[0])

        res = minimize(cost, pose, method="Nelder-Mead",
                       options={"maxiter": p.polish_iters, "xatol": 1e-3, "fatol": 1e-5,
                                "initial_simplex": pose + np.array([[0, 0, 0], [0.03, 0, 0], [0, 0.03, 0],
                                                                    [0, 0, 0.03]])})
        if res.fun < e:
            pose, e = np.asarray(res.x, dtype=float), float(res.fun)
    pose[2] = float(wrap_angle(pose[2]))
    return LocalizationResult(pose, e, len(poses), e <= p.success_error, int(owners[best]))
