"""Feature-based sonar localizer (Kim, Pearce & Amato, Fig. 6) and the uncertainty ellipse.

LOCALIZER (the paper's Fig. 6): sectors meeting the uncertainty ellipse -> their features F1; scan
features F2 (of the raw and, with ``filter``, the Fig. 11 filtered scan) -> for each pair a pose from
the map corner and its two adjacent walls -> keep poses within ``ellipse_distance`` of the ellipse
(and in free space) -> synthetic scan of the known map from each -> smallest error.

Pose from a (map corner, scan) pair (the paper does not say how; our choice): the scan's wall
observations (local minima: the foot of a wall's perpendicular, bearing and distance) matched to the
corner's two walls give the heading (map normal angle minus measured bearing) and the position from
the two wall-distance equations ``n_i . (p - c) = d_i``. With only one wall matched, the corner's
measured range/bearing (an M point) gives the position.

Extensions beyond the paper, each a switch of :class:`~parcover_env.localization.sonar.config.SonarLocalizerConfig`
(all on by default; ``SonarLocalizerConfig.paper_method()`` turns them off):

* ``arc_fallback``: a pair whose walls give no pose near the ellipse tries poses on the circle of
  the corner's measured range (:func:`arc_candidates`);
* ``grid_fallback``: when no feature pose explains the scan, scan matching over a grid of poses in
  the ellipse around the heading estimate;
* ``polish``: the best pose is polished by minimizing the clipped scan error (Nelder-Mead); the
  paper only suggests least squares to cut its 13 cm error.

``benchmarks/sonar_localization.py`` measures each of them against the paper's method alone.

Compiled (issue 40): the characteristic points and the Fig. 11 filter (:mod:`.scan_kernels`), the
candidate poses, the ellipse distance, the scan error and the polish's Nelder-Mead
(:mod:`.localizer_kernels`) run in numba with the float operations, LAPACK/BLAS calls and order of the
numpy/scipy code they replaced (kept as ``tests/references/sonar_localizer.py``): the results are the
same bit for bit (``tests/localization/sonar/test_localizer_kernels.py``, ``test_localizer_pinned.py``),
at 0.4-1.8 ms of CPU per scan (median per row and map) instead of 5-31 ms (``benchmarks/sonar_localization.py
--reference``; docs/fidelity.md).
Shapely still decides which sectors meet the grown ellipse, which candidates lie in free space and
which arc poses lie in the grown ellipse (one vectorized call each).

The candidates' scan errors (the feature poses', then the grid's, nearest the region's centre first) come
from :func:`~parcover_env.localization.sonar.grid_kernels.bounded_scan_errors`: each error bit for bit, or
inf for a pose whose error provably exceeds a smaller one found before it, so the pose chosen is the same
(``tests/localization/sonar/test_grid_kernels.py``). A skipped pose's sonar stops before its second legs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
import shapely
from scipy.optimize import minimize

from parcover_env.config import SonarConfig
from parcover_env.geometry import wrap_angle
from parcover_env.geometry.numpy_order import argsort4_table
from parcover_env.geometry.rays import disc_planes
from parcover_env.localization.sonar import grid_kernels, scan_kernels
from parcover_env.localization.sonar import localizer_kernels as kern
from parcover_env.localization.sonar.features import (
    MapFeature,
    ScanPoints,
    map_features,
)
from parcover_env.localization.sonar.filter import filter_scan
from parcover_env.localization.sonar.params import SonarLocalizerParams
from parcover_env.localization.sonar.sectors import Sector
from parcover_env.sensors.sonar import beam_kernel_arguments, simulate_beams
from parcover_env.sensors.sonar_kernels import Discs

__all__ = ["Ellipse", "LocalizationResult", "localize", "synthetic_scans", "scan_error", "pose_candidates"]


@lru_cache(maxsize=8)
def _unit_circle(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Cosines and sines of ``n`` angles evenly spaced over a turn (numpy's; read-only)."""
    t = np.linspace(0, 2 * math.pi, n, endpoint=False)
    cos_t, sin_t = np.cos(t), np.sin(t)
    cos_t.setflags(write=False)
    sin_t.setflags(write=False)
    return cos_t, sin_t


@dataclass(frozen=True)
class Ellipse:
    """Position uncertainty: ``center (2,)``, semi-axes ``axes (a, b)`` (m), orientation ``angle`` (rad)."""

    center: tuple[float, float]
    axes: tuple[float, float]
    angle: float = 0.0

    def __post_init__(self) -> None:
        c, a = np.asarray(self.center, dtype=float), np.asarray(self.axes, dtype=float)
        if c.shape != (2,) or a.shape != (2,) or not np.all(np.isfinite(c)) or not np.all(np.isfinite(a)):
            raise ValueError(f"Ellipse needs center (x, y) and axes (a, b), got {self.center}, {self.axes}")
        if np.any(a < 0):
            raise ValueError(f"Ellipse axes must be >= 0, got {self.axes}")
        object.__setattr__(self, "center", (float(c[0]), float(c[1])))
        object.__setattr__(self, "axes", (float(a[0]), float(a[1])))

    @classmethod
    def from_covariance(cls, center, covariance, n_sigma: float = 2.0) -> Ellipse:
        """The ``n_sigma`` ellipse of a 2x2 position covariance (m^2) around ``center``: semi-axes
        ``n_sigma * sqrt(eigenvalues)``, oriented along the major eigenvector."""
        cov = np.asarray(covariance, dtype=float)
        if cov.shape != (2, 2) or not np.all(np.isfinite(cov)) or abs(cov[0, 1] - cov[1, 0]) > 1e-9 * (
                1 + np.abs(cov).max()):
            raise ValueError(f"covariance must be a finite symmetric 2x2 matrix, got {cov.tolist()}")
        w, v = np.linalg.eigh(0.5 * (cov + cov.T))
        if w[0] < -1e-12 * (1 + abs(w[1])):
            raise ValueError(f"covariance must be positive semi-definite, eigenvalues {w.tolist()}")
        if not n_sigma > 0:
            raise ValueError(f"n_sigma must be > 0, got {n_sigma}")
        sd = np.sqrt(np.maximum(w, 0.0))
        angle = math.atan2(v[1, 1], v[0, 1])
        angle = angle - math.pi if angle > math.pi / 2 else angle + math.pi if angle <= -math.pi / 2 else angle
        return cls(tuple(center), (float(n_sigma * sd[1]), float(n_sigma * sd[0])), float(angle))

    def grow(self, distance: float, rotation: float, rate_distance: float = 0.1,
             rate_rotation: float = 0.05) -> Ellipse:
        """Grow both axes linearly: ``rate_distance`` m per metre travelled plus ``rate_rotation`` m per
        radian turned (Kim, Pearce & Amato: the ellipse grows linearly as the robot translates or rotates)."""
        g = rate_distance * abs(float(distance)) + rate_rotation * abs(float(rotation))
        return replace(self, axes=(self.axes[0] + g, self.axes[1] + g))

    def moved(self, center) -> Ellipse:
        return replace(self, center=tuple(center))

    def polygon(self, n: int = 64) -> shapely.Polygon:
        cos_t, sin_t = _unit_circle(int(n))
        a, b = max(self.axes[0], 1e-6), max(self.axes[1], 1e-6)
        c, s = math.cos(self.angle), math.sin(self.angle)
        x, y = a * cos_t, b * sin_t
        return shapely.Polygon(np.stack([self.center[0] + c * x - s * y, self.center[1] + s * x + c * y], 1))

    def distance(self, points) -> np.ndarray:
        """Distance from each point ``(P, 2)`` to the ellipse (0 inside); boundary sampled at 256 points."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        out = np.empty(len(p))
        kern.ellipse_distances(np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1]), self.kernel_record(),
                                    kern.EDGE_COS, kern.EDGE_SIN, out)
        return out

    def kernel_record(self) -> np.ndarray:
        """``(cx, cy, cos angle, sin angle, a, b)`` with the semi-axes at least 1e-9: the ellipse as
        :func:`~parcover_env.localization.sonar.localizer_kernels.ellipse_distance` reads it."""
        return np.array([self.center[0], self.center[1], math.cos(self.angle), math.sin(self.angle),
                         max(self.axes[0], 1e-9), max(self.axes[1], 1e-9)])

@dataclass(frozen=True, eq=False)
class LocalizationResult:
    pose: np.ndarray | None
    """Best pose (x, y, theta) or None."""
    error: float
    """Mean clipped |measured - synthetic| range error of the best pose (m); inf if none."""
    candidates_tried: int
    """Synthetic scans computed (poses that passed the ellipse check)."""
    success: bool
    feature: int = -1
    """Index of the map feature that produced the best pose."""


def synthetic_scans(poses, scan_angles, segments, sonar: SonarConfig) -> np.ndarray:
    """Noise-free scans ``(H, n)`` of the map from each pose ``(H, 3)``."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    axes = poses[:, 2:3] + np.asarray(scan_angles, dtype=float)[None, :]
    return simulate_beams(sonar, poses[:, :2], axes, segments, np.zeros((0, 2)), 0.0,
                          np.full(len(poses), -1))


def scan_error(measured, synthetic, clip: float, trim: float = 0.0) -> np.ndarray:
    """Mean clipped absolute range error per synthetic scan (rows), over the best ``1 - trim``
    share of the readings (``trim`` drops the worst: other robots, multipath, unknown obstacles).
    Compiled (:func:`~parcover_env.localization.sonar.localizer_kernels.scan_errors`): the kept errors
    are summed in ascending order with a trim, in reading order without."""
    m = np.ascontiguousarray(measured, dtype=float)
    synth = np.ascontiguousarray(np.atleast_2d(synthetic), dtype=float)
    if synth.shape[1:] != m.shape or m.ndim != 1:
        raise ValueError(f"scan_error: synthetic scans {synth.shape} do not match the measured scan {m.shape}")
    keep = len(m) - int(math.floor(trim * len(m)))
    out = np.empty(len(synth))
    kern.scan_errors(m, synth, float(clip), keep, out)
    return out


def _scan_arrays(scan: ScanPoints) -> tuple[np.ndarray, np.ndarray]:
    walls = np.array([(w.bearing, w.distance, w.index) for w in scan.walls], dtype=float).reshape(-1, 3)
    corners = np.array([(k.bearing, k.range, k.index) for k in scan.corners], dtype=float).reshape(-1, 3)
    return walls, corners


def pose_candidates(feature: MapFeature, scan: ScanPoints, params: SonarLocalizerParams) -> list[np.ndarray]:
    """Poses (x, y, theta) that explain ``feature`` by the scan's walls and corners (compiled:
    :func:`~parcover_env.localization.sonar.localizer_kernels.pair_poses`, the ones :func:`localize` uses)."""
    walls, corners = _scan_arrays(scan)
    out = np.empty((len(walls) ** 2 + 2 * len(walls) * len(corners), 3))
    table = _build_table([feature])
    m = kern.pair_poses(table.points[0], table.normals[0], bool(table.solvable[0]), walls, corners,
                        math.radians(params.heading_tol_deg), float(params.line_tol), out, 0)
    return list(out[:m])


def arc_candidates(feature: MapFeature, scan: ScanPoints, region: shapely.Geometry,
                   step: float = 0.03) -> list[np.ndarray]:
    """Fallback beyond the paper (``arc_fallback``) when no wall of the corner shows its perpendicular
    foot: poses on the circle of the measured corner range around the corner, inside the corner's
    wedge and ``region`` (the grown ellipse), every ``step`` metres of arc; heading from the corner's
    measured bearing (compiled: :func:`~parcover_env.localization.sonar.localizer_kernels.arc_poses`)."""
    _, corners = _scan_arrays(scan)
    walls = np.ascontiguousarray(feature.walls, dtype=float)
    out = np.empty((kern.arc_count(walls, corners, float(step)), 3))
    kern.arc_poses(np.ascontiguousarray(feature.point, dtype=float), walls, corners, float(step), out, 0)
    return list(out[shapely.contains_xy(region, out[:, 0], out[:, 1])])


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


def _bounded_errors(r: np.ndarray, poses: np.ndarray, a: np.ndarray, segs: np.ndarray, sonar: SonarConfig,
                    p: SonarLocalizerParams, best: float,
                    centre: tuple[float, float, float] | None = None) -> np.ndarray:
    """The candidate poses' ``(H, 3)`` scan errors (:func:`scan_error` of their :func:`synthetic_scans`, bit for
    bit), inf for a pose whose error provably exceeds ``best`` (e.g. the feature poses' smallest, before the
    grid's) and those of the poses before it
    (:func:`~parcover_env.localization.sonar.grid_kernels.bounded_scan_errors`): the smallest error and the
    first pose with it, what the localizer uses, are the same. ``centre`` ``(x, y, heading)``: the poses are
    tried nearest it first (spot by spot, the nearest heading first): a small error found early skips more
    (the same numbers: the order only decides which larger errors are skipped)."""
    n = len(poses)
    order = None
    if centre is not None and n > 1:
        spot = np.cumsum(np.r_[0, (np.diff(poses[:, 0]) != 0) | (np.diff(poses[:, 1]) != 0)])
        dist = np.hypot(poses[:, 0] - centre[0], poses[:, 1] - centre[1])
        order = np.lexsort((np.abs(wrap_angle(poses[:, 2] - centre[2])), spot, dist))
        poses = poses[order]
    axes = np.ascontiguousarray(poses[:, 2:3] + a[None, :])
    walls, offsets, share, rules = beam_kernel_arguments(sonar, segs, axes)
    discs = Discs(*disc_planes(np.zeros((0, 2)), 0.0, np.full(n, -1), n))
    out = np.empty(n)
    keep = len(r) - int(math.floor(p.error_trim * len(r)))
    target = grid_kernels.ScanTarget(measured=np.ascontiguousarray(r, dtype=float), clip=float(p.error_clip),
                                     keep=keep, best=float(best))
    grid_kernels.bounded_scan_errors(np.ascontiguousarray(poses[:, 0]), np.ascontiguousarray(poses[:, 1]), axes,
                                     offsets, share, walls, discs, rules, target, out)
    if order is not None:
        out[order] = out.copy()
    return out


_ARGSORT4 = argsort4_table()
_OFF_NORMAL = float(np.radians(20.0))
"""A wall's fitted normal replaces its plateau bearing when within this of it (rad), as in ``features``."""
_ARC_STEP = 0.03
"""Arc step of :func:`arc_candidates` in the localizer (m)."""


def _scan_rows(r: np.ndarray, sin_a: np.ndarray, cos_a: np.ndarray, range_max: float,
               p: SonarLocalizerParams) -> tuple[np.ndarray, np.ndarray]:
    """The scan's walls and corners ``(W, 3), (K, 3)`` (rows bearing, range, index) as
    :func:`~parcover_env.localization.sonar.features.characteristic_points` finds them."""
    _, corners, walls = scan_kernels.characteristic_points(
        r, sin_a, cos_a, float(range_max), float(p.far_margin), float(p.jump_threshold), float(p.prominence),
        int(p.window), float(p.plateau_tol), float(p.line_tol), _OFF_NORMAL)
    return walls, corners


_TABLES: dict[int, tuple[list, kern.FeatureTable]] = {}
"""The last few feature lists' tables (keyed by identity; the list is held, so its id stays its own)."""


_POLYGONS: dict[int, tuple[list, np.ndarray]] = {}
"""The last few sector lists' polygons as an array (keyed by identity; the list is held)."""


def _sector_polygons(sectors: list[Sector]) -> np.ndarray:
    """The sectors' polygons as one array, for one vectorized ``intersects`` (the same GEOS predicate)."""
    hit = _POLYGONS.get(id(sectors))
    if hit is not None and hit[0] is sectors and len(hit[1]) == len(sectors):
        return hit[1]
    polys = np.empty(len(sectors), dtype=object)
    polys[:] = [s.polygon for s in sectors]
    if len(_POLYGONS) >= 16:
        _POLYGONS.pop(next(iter(_POLYGONS)))
    _POLYGONS[id(sectors)] = (sectors, polys)
    return polys


def _feature_table(feats: list[MapFeature]) -> kern.FeatureTable:
    """The map features as arrays for the compiled candidates, built once per feature list."""
    hit = _TABLES.get(id(feats))
    if hit is not None and hit[0] is feats and len(feats) == len(hit[1].solvable):
        return hit[1]
    table = _build_table(feats)
    if len(_TABLES) >= 16:
        _TABLES.pop(next(iter(_TABLES)))
    _TABLES[id(feats)] = (feats, table)
    return table


def _build_table(feats: list[MapFeature]) -> kern.FeatureTable:
    solvable = np.ones(len(feats), dtype=bool)
    for k, f in enumerate(feats):
        try:
            np.linalg.solve(f.normals, np.ones(2))
        except np.linalg.LinAlgError:  # walls along one line: no pose from their two distances
            solvable[k] = False
    table = kern.FeatureTable(np.array([f.point for f in feats], dtype=float).reshape(-1, 2),
                          np.array([f.normals for f in feats], dtype=float).reshape(-1, 2, 2),
                          np.array([f.walls for f in feats], dtype=float).reshape(-1, 2, 2), solvable)
    return table


def _feature_poses(feats: list[MapFeature], f1: np.ndarray, scans: list[tuple[np.ndarray, np.ndarray]],
                   ellipse: Ellipse, region: shapely.Geometry,
                   p: SonarLocalizerParams) -> tuple[np.ndarray, np.ndarray]:
    """Fig. 6 steps 5-7: for each feature of ``f1`` and each scan (walls, corners), the poses of
    :func:`pose_candidates` within ``ellipse_distance`` of the ellipse, or, with ``arc_fallback`` and
    none, those of :func:`arc_candidates` inside ``region``; ``(poses (M, 3), owners (M,))`` in that order."""
    table = _feature_table(feats)
    walls = np.ascontiguousarray(np.concatenate([s[0] for s in scans]).reshape(-1, 3))
    corners = np.ascontiguousarray(np.concatenate([s[1] for s in scans]).reshape(-1, 3))
    wstart = np.concatenate([[0], np.cumsum([len(s[0]) for s in scans])]).astype(np.int64)
    cstart = np.concatenate([[0], np.cumsum([len(s[1]) for s in scans])]).astype(np.int64)
    rules = kern.CandidateRules(math.radians(p.heading_tol_deg), float(p.line_tol), ellipse.kernel_record(),
                                kern.EDGE_COS, kern.EDGE_SIN, float(p.ellipse_distance), bool(p.arc_fallback),
                                _ARC_STEP)
    poses, pair, arcs, arc_pair = kern.feature_candidates(table, f1, kern.ScanRows(walls, wstart, corners, cstart),
                                                          rules)
    if len(arcs):
        inside = shapely.contains_xy(region, arcs[:, 0], arcs[:, 1])
        poses, pair = np.concatenate([poses, arcs[inside]]), np.concatenate([pair, arc_pair[inside]])
        order = np.argsort(pair, kind="stable")
        poses, pair = poses[order], pair[order]
    return poses, f1[pair // len(scans)] if len(pair) else np.zeros(0, dtype=np.int64)


def _polish(pose: np.ndarray, r: np.ndarray, a: np.ndarray, map_model, ellipse: Ellipse, p: SonarLocalizerParams,
            sonar: SonarConfig) -> tuple[np.ndarray, float]:
    """The polish (extension ``polish``): Nelder-Mead from ``pose`` over the clipped, trimmed scan error,
    a pose outside the free space or ``ellipse_distance`` or more from the ellipse costing
    ``error_clip``. Compiled (:func:`~parcover_env.localization.sonar.localizer_kernels.nelder_mead`); a
    pose within 1e-9 m of a wall leaves the decision to shapely, through scipy's Nelder-Mead (the same
    steps). Returns the minimizer and its cost."""
    segs = map_model.segments
    keep = len(r) - int(math.floor(p.error_trim * len(r)))
    axes = pose[2] + a[None, :]
    walls, offsets, share, rules = beam_kernel_arguments(sonar, segs, axes)
    discs = Discs(*disc_planes(np.zeros((0, 2)), 0.0, np.full(1, -1), 1))
    fit = kern.ScanFit(measured=r, angles=a, clip=float(p.error_clip), keep=keep, ell=ellipse.kernel_record(),
                       ecos=kern.EDGE_COS, esin=kern.EDGE_SIN, reach=float(p.ellipse_distance), free=segs, walls=walls,
                       offsets=offsets, share=share, discs=discs, rules=rules, rmax=float(sonar.range_max))
    x, f, undecided = kern.nelder_mead(pose, kern.Simplex(0.03, int(p.polish_iters), 1e-3, 1e-5, _ARGSORT4), fit)
    if not undecided:
        return x, float(f)

    def cost(x):
        if not map_model.contains(x[None, :2])[0] or ellipse.distance(x[None, :2])[0] >= p.ellipse_distance:
            return p.error_clip
        return float(scan_error(r, synthetic_scans(x[None], a, segs, sonar), p.error_clip, p.error_trim)[0])

    res = minimize(cost, pose, method="Nelder-Mead",
                   options={"maxiter": p.polish_iters, "xatol": 1e-3, "fatol": 1e-5,
                            "initial_simplex": pose + np.array([[0, 0, 0], [0.03, 0, 0], [0, 0.03, 0], [0, 0, 0.03]])})
    return np.asarray(res.x, dtype=float), float(res.fun)


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
    meets = shapely.intersects(_sector_polygons(sectors), region)
    f1 = sorted(set().union(*[s.features for s, hit in zip(sectors, meets.tolist(), strict=True) if hit]))
    # Kim, Pearce & Amato Fig. 11: features also come from the filtered scan (too-long readings moved onto the
    # nearest walls); the raw scan's features stay candidates (the filter can erase a wall's end)
    sin_a, cos_a = np.ascontiguousarray(np.sin(a)), np.ascontiguousarray(np.cos(a))
    r = np.ascontiguousarray(r)
    scans = [_scan_rows(r, sin_a, cos_a, sonar.range_max, p)]
    if p.filter:
        r_filt = filter_scan(r, a, sonar.range_max, p.filter_repeats, p.filter_half_window, p.filter_line_tol)
        if not np.array_equal(r_filt, r):
            scans.insert(0, _scan_rows(r_filt, sin_a, cos_a, sonar.range_max, p))
    poses, owners = _feature_poses(feats, np.array(f1, dtype=np.int64), scans, ellipse, region, p)
    segs = map_model.segments
    keep = (ellipse.distance(poses[:, :2]) < p.ellipse_distance) & map_model.contains(poses[:, :2])
    if heading is not None:
        tol = math.radians(p.heading_prior_tol_deg) if heading_tol is None else float(heading_tol)
        keep &= np.abs(wrap_angle(poses[:, 2] - float(heading))) <= tol
    poses, owners = poses[keep], owners[keep]
    uniq = kern.first_unique(np.round(np.column_stack([poses[:, :2] / 0.01, poses[:, 2] / 0.01])))[: p.max_candidates]
    poses, owners = poses[uniq], owners[uniq]
    # the feature poses' and the grid's errors: each one's exactly, or inf where it provably exceeds an error
    # before it (only the first smallest is used)
    err = _bounded_errors(r, poses, a, segs, sonar, p, math.inf) if len(poses) else np.zeros(0)
    if heading is not None and p.grid_fallback and (len(err) == 0 or err.min() > p.success_error):
        # no feature pose explains the scan: scan matching over the uncertainty region instead
        grid = _grid_candidates(ellipse, float(heading), map_model, p)
        poses = np.concatenate([poses, grid])
        owners = np.concatenate([owners, np.full(len(grid), -1)])
        best = float(err.min()) if len(err) else math.inf
        err = np.concatenate([err, _bounded_errors(r, grid, a, segs, sonar, p, best,
                                                   (ellipse.center[0], ellipse.center[1], float(heading)))])
    if len(poses) == 0:
        return LocalizationResult(None, math.inf, 0, False)
    best = int(np.argmin(err))
    pose, e = poses[best].copy(), float(err[best])
    if p.polish:
        res = _polish(pose, r, a, map_model, ellipse, p, sonar)
        if res[1] < e:
            pose, e = res
    pose[2] = float(wrap_angle(pose[2]))
    return LocalizationResult(pose, e, len(poses), e <= p.success_error, int(owners[best]))
