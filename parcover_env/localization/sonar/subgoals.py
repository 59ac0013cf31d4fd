"""Subgoal selection for sonar localization (Kim, Pearce & Amato §3): scan-angle optimization and rearrangement.

Scan-angle optimization (§3.1, eq. 1). A path is cut into closely spaced nodes. At node N a map
feature F (a concave corner with walls W1, W2) is *available* when it is in line of sight within
``[range_min, range_max - range_margin]`` (sensor range condition), both adjacent walls are at least
``min_wall_length`` long and at least ``min_walls_seen`` of them return ``>= min_readings`` scan
readings (wall length condition, "at least two readings along that wall"). Readings on a wall are
counted analytically: the part of the wall within range and — for a specular sonar — within
``incidence_max`` of the wall's normal, as an angle seen from N, divided by the scan step.

Bias (eq. 1). The paper writes ``theta_k = angle(N F) - angle(W_k)`` and ``B = |theta_1 - theta_2|``;
read literally that difference does not depend on N. Its own example (theta_1 = 15 deg,
theta_2 = 75 deg, B = 60 deg) and its optimum ("the line of sight exactly bisects the space between the
walls") fix the meaning used here: theta_k is the unsigned angle between the line of sight and wall k
at the corner, and ``B = | theta_1 - theta_2 |`` is 0 on the corner's bisector.

Blocking (§3.2): ``A_i`` is the angle range robot i needs to scan its feature (from its farthest
useful point of wall 1 through the corner to that of wall 2) minus the bearings blocked by other
robots (a disc at range r blocks ``asin(R / r) + cone / 2`` either side of its bearing); a teammate
blocks robot i when it lowers ``A_i`` (:func:`unblocked_scan_angle`). Rearrangement maximizes the
smaller ``A_i`` of a pair over each robot's legal space S_i (:func:`best_pair`; "in general, they can
simply move along their paths").

Bisector construction (§4, the implementation behind Fig. 9(a) -> (b)): take the perpendicular
bisector of the segment from the robots' centre c to the feature F. A robot whose path crosses it
moves its subgoal to the crossing (the one nearest its old subgoal along the path); the other robot
takes the point of the bisector closest to its old subgoal (slid along the bisector, away from the
first, to keep ``min_separation``). Both then stand abreast across the line of sight to F, half as
far from it, so neither blocks the other's scan of F (:func:`bisector_rearrangement`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from parcover_env.geometry import atan2, wrap_angle
from parcover_env.localization.sonar.features import MapFeature
from parcover_env.localization.sonar.sectors import visible_features

__all__ = ["PathNodes", "densify", "scan_bias", "wall_readings", "NodeScores", "score_nodes",
           "choose_subgoal", "team_subgoal", "scan_interval", "unblocked_scan_angle", "unblocked_angles",
           "best_pair", "PairChoice", "bisector_rearrangement", "Rearrangement"]


@dataclass(frozen=True, eq=False)
class PathNodes:
    """A polyline resampled into nodes: ``xy (P, 2)`` and arclength ``s (P,)`` (m, from ``s[0]``)."""

    xy: np.ndarray
    s: np.ndarray

    def index(self, sigma: float) -> int:
        """Index of the node nearest to arclength ``sigma`` (clamped to the path)."""
        return int(np.argmin(np.abs(self.s - sigma)))

    def point(self, sigma: float) -> np.ndarray:
        """Point at arclength ``sigma`` (linear interpolation, clamped to the ends)."""
        return np.array([np.interp(sigma, self.s, self.xy[:, 0]), np.interp(sigma, self.s, self.xy[:, 1])])

    @property
    def length(self) -> float:
        return float(self.s[-1] - self.s[0])


def densify(path, step: float = 0.05, s0: float = 0.0) -> PathNodes:
    """Nodes every ``<= step`` metres along ``path (K, 2)`` (all vertices kept, repeated ones dropped);
    arclength starts at ``s0``."""
    p = np.asarray(path, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 1 or not np.all(np.isfinite(p)):
        raise ValueError(f"path must be a finite (K, 2) array with K >= 1, got shape {p.shape}")
    if not step > 0:
        raise ValueError(f"step must be > 0, got {step}")
    keep = np.concatenate([[True], np.hypot(*np.diff(p, axis=0).T) > 1e-9])
    p = p[keep]
    pts = [p[:1]]
    for a, b in zip(p[:-1], p[1:], strict=True):
        k = max(1, int(math.ceil(np.hypot(*(b - a)) / step)))
        t = np.arange(1, k + 1)[:, None] / k
        pts.append(a + t * (b - a))
    xy = np.concatenate(pts)
    s = s0 + np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    return PathNodes(xy, s)


def scan_bias(nodes, features: list[MapFeature]) -> np.ndarray:
    """``(P, F)`` bias B (rad) of eq. 1: ``| theta_1 - theta_2 |`` with theta_k the unsigned angle at the
    corner between the line of sight to node N and wall k."""
    xy = np.atleast_2d(np.asarray(nodes, dtype=float))
    if not features:
        return np.zeros((len(xy), 0))
    c = np.stack([f.point for f in features])
    w = np.stack([f.walls for f in features])  # (F, 2, 2)
    v = xy[:, None, :] - c[None, :, :]
    phi = atan2(v[..., 1], v[..., 0])
    a1, a2 = atan2(w[:, 0, 1], w[:, 0, 0]), atan2(w[:, 1, 1], w[:, 1, 0])
    t1 = np.abs(wrap_angle(phi - a1[None, :]))
    t2 = np.abs(wrap_angle(phi - a2[None, :]))
    return np.abs(t1 - t2)


def _echo_span(xy: np.ndarray, f: MapFeature, k: int, range_max: float, incidence_max: float):
    """Per node: the wall-k interval ``[lo, hi]`` (arclength from the corner) that echoes, and
    whether it is non-empty."""
    rel = xy - f.point
    d = rel @ f.normals[k]
    s0 = rel @ f.walls[k]
    half = np.sqrt(np.maximum(range_max ** 2 - d ** 2, 0.0))
    if incidence_max < math.pi / 2 - 1e-9:
        half = np.minimum(half, np.maximum(d, 0.0) * math.tan(incidence_max))
    lo = np.maximum(s0 - half, 0.0)
    hi = np.minimum(s0 + half, f.lengths[k])
    return lo, hi, (d > 1e-6) & (hi > lo)


def wall_readings(nodes, feature: MapFeature, range_max: float, step: float,
                  incidence_max: float = math.pi / 2) -> np.ndarray:
    """``(P, 2)`` number of scan readings (every ``step`` rad) that echo from each wall of ``feature``.
    ``incidence_max`` (rad) models a specular sonar; pi/2 = ideal rays. Occlusion is not checked."""
    xy = np.atleast_2d(np.asarray(nodes, dtype=float))
    out = np.zeros((len(xy), 2))
    for k in (0, 1):
        lo, hi, ok = _echo_span(xy, feature, k, range_max, incidence_max)
        p_lo = feature.point + lo[:, None] * feature.walls[k]
        p_hi = feature.point + hi[:, None] * feature.walls[k]
        a_lo = atan2(*(p_lo - xy)[:, ::-1].T)
        a_hi = atan2(*(p_hi - xy)[:, ::-1].T)
        span = np.abs(wrap_angle(a_hi - a_lo))
        out[:, k] = np.where(ok, np.floor(span / step) + 1.0, 0.0)
    return out


@dataclass(frozen=True, eq=False)
class NodeScores:
    """Per node: ``bias (P,)`` of the best available feature (inf: none) and its index ``feature (P,)``
    (-1: none); ``available (P, F)`` the availability matrix."""

    bias: np.ndarray
    feature: np.ndarray
    available: np.ndarray


def score_nodes(nodes, map_model, features: list[MapFeature], range_min: float, range_max: float,
                scan_step: float, incidence_max: float = math.pi / 2, min_wall_length: float = 0.3,
                min_readings: int = 2, min_walls_seen: int = 1, range_margin: float = 0.1) -> NodeScores:
    """Score every node by eq. 1 over the features available there (sensor range and wall length
    conditions, see the module docstring)."""
    xy = np.atleast_2d(np.asarray(nodes, dtype=float))
    if xy.shape[1] != 2:
        raise ValueError(f"nodes must be (P, 2), got {xy.shape}")
    if not (0 <= range_min < range_max and scan_step > 0):
        raise ValueError(f"need 0 <= range_min < range_max and scan_step > 0, got {range_min}, {range_max}, "
                         f"{scan_step}")
    if min_walls_seen not in (0, 1, 2):
        raise ValueError(f"min_walls_seen must be 0, 1 or 2, got {min_walls_seen}")
    n_f = len(features)
    avail = visible_features(xy, map_model, features, range_max - range_margin) if n_f else \
        np.zeros((len(xy), 0), bool)
    for j, f in enumerate(features):
        dist = np.hypot(*(xy - f.point).T)
        seen = (wall_readings(xy, f, range_max, scan_step, incidence_max) >= min_readings).sum(axis=1)
        long_enough = bool(np.all(f.lengths >= min_wall_length))
        avail[:, j] &= (dist >= range_min) & (seen >= min_walls_seen) & long_enough
    bias = np.where(avail, scan_bias(xy, features), np.inf)
    best = np.argmin(bias, axis=1) if n_f else np.zeros(len(xy), dtype=int)
    b = bias[np.arange(len(xy)), best] if n_f else np.full(len(xy), np.inf)
    return NodeScores(b, np.where(np.isfinite(b), best, -1), avail)


def choose_subgoal(s: np.ndarray, bias: np.ndarray, s_lo: float, s_hi: float, tie_tol: float) -> int:
    """Index of the node with ``s_lo <= s <= s_hi`` of minimum bias; among nodes within ``tie_tol`` of
    it, the farthest along. No feature available in the window: the farthest node (the original
    algorithm's choice: the last node before the uncertainty grows too large)."""
    s, bias = np.asarray(s, dtype=float), np.asarray(bias, dtype=float)
    win = np.nonzero((s >= s_lo - 1e-9) & (s <= s_hi + 1e-9))[0]
    if len(win) == 0:
        return int(np.argmin(np.abs(s - np.clip(s_hi, s[0], s[-1]))))
    b = bias[win]
    if not np.isfinite(b).any():
        return int(win[-1])
    good = win[b <= b.min() + tie_tol]
    return int(good[-1])


def team_subgoal(paths: list[PathNodes], biases: list[np.ndarray], lags: np.ndarray, sigma_lo: float,
                 sigma_hi: float, step: float, tie_tol: float) -> float:
    """Team arclength sigma in ``[sigma_lo, sigma_hi]``: robot i's subgoal is on its path at
    ``sigma - lags[i]`` (clamped to its path). Minimizes the worst robot's bias (§3: the subgoal that
    optimizes the scan angle for all robots); ties within ``tie_tol``: the largest sigma."""
    if sigma_hi < sigma_lo:
        sigma_lo = sigma_hi
    grid = np.arange(sigma_lo, sigma_hi + 1e-9, step) if sigma_hi > sigma_lo else np.array([sigma_hi])
    if grid[-1] < sigma_hi - 1e-9:
        grid = np.append(grid, sigma_hi)
    worst = np.zeros(len(grid))
    for p, b, lag in zip(paths, biases, lags, strict=True):
        idx = np.array([p.index(g - lag) for g in grid])
        worst = np.maximum(worst, b[idx])
    s_idx = choose_subgoal(grid, worst, sigma_lo, sigma_hi, tie_tol)
    return float(grid[s_idx])


def scan_interval(xy, feature: MapFeature, range_max: float, incidence_max: float) -> tuple[float, float]:
    """Bearings ``(start, width)`` (rad, counter-clockwise) a robot at ``xy`` needs to scan ``feature``:
    from the farthest echoing point of wall 1 through the corner to that of wall 2."""
    p = np.asarray(xy, dtype=float)[None, :]
    bearings = [math.atan2(*(feature.point - p[0])[::-1])]
    for k in (0, 1):
        lo, hi, ok = _echo_span(p, feature, k, range_max, incidence_max)
        if ok[0]:
            q = feature.point + hi[0] * feature.walls[k]
            bearings.append(math.atan2(*(q - p[0])[::-1]))
    ref = bearings[0]
    rel = [float(wrap_angle(b - ref)) for b in bearings]
    lo, hi = min(rel), max(rel)
    return ref + lo, hi - lo


def unblocked_scan_angle(xy, feature: MapFeature, others, robot_radius: float, range_max: float,
                         incidence_max: float = math.pi / 2, cone: float = 0.0,
                         margin: float = math.radians(2), resolution: float = math.radians(0.5)) -> float:
    """``A_i`` of §3.2: width (rad) of the scan interval of ``feature`` seen from ``xy`` (widened by
    ``margin`` each side) not blocked by the discs of radius ``robot_radius`` at ``others (K, 2)``."""
    start, width = scan_interval(xy, feature, range_max, incidence_max)
    start, width = start - margin, width + 2 * margin
    b = start + np.arange(0.0, width + 1e-12, resolution)
    o = np.atleast_2d(np.asarray(others, dtype=float)).reshape(-1, 2)
    free = np.ones(len(b), dtype=bool)
    p = np.asarray(xy, dtype=float)
    for q in o:
        r = float(np.hypot(*(q - p)))
        if r < 1e-9:
            return 0.0
        half = math.asin(min(1.0, robot_radius / r)) + cone / 2
        free &= np.abs(wrap_angle(b - math.atan2(q[1] - p[1], q[0] - p[0]))) > half
    return float(free.sum() * resolution)


def unblocked_angles(points, feature: MapFeature, others, robot_radius: float, range_max: float,
                     incidence_max: float = math.pi / 2, cone: float = 0.0, margin: float = math.radians(2),
                     resolution: float = math.radians(0.5)) -> np.ndarray:
    """``(K, M)``: :func:`unblocked_scan_angle` of ``feature`` from each of ``points (K, 2)`` with one
    teammate at each of ``others (M, 2)`` (rad)."""
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    oth = np.atleast_2d(np.asarray(others, dtype=float)).reshape(-1, 2)
    out = np.zeros((len(pts), len(oth)))
    for k, p in enumerate(pts):
        start, width = scan_interval(p, feature, range_max, incidence_max)
        b = start - margin + np.arange(0.0, width + 2 * margin + 1e-12, resolution)
        rel = oth - p
        r = np.hypot(*rel.T)
        half = np.arcsin(np.minimum(1.0, robot_radius / np.maximum(r, 1e-9))) + cone / 2
        free = np.abs(wrap_angle(b[None, :] - atan2(rel[:, 1], rel[:, 0])[:, None])) > half[:, None]
        out[k] = np.where(r > 1e-9, free.sum(axis=1) * resolution, 0.0)
    return out


@dataclass(frozen=True)
class PairChoice:
    """Result of :func:`best_pair`: candidate indices ``(a, b)`` and the pair's minimum unblocked
    scan angle there (rad); ``(-1, -1)`` and ``-inf`` without a valid pair."""

    a: int
    b: int
    value: float


def best_pair(cands_a, cands_b, feature: MapFeature, min_separation: float, robot_radius: float,
              range_max: float, incidence_max: float = math.pi / 2, cone: float = 0.0,
              cost=None, resolution: float = math.radians(0.5)) -> PairChoice:
    """§3.2: subgoals ``N_a`` in ``cands_a (K, 2)`` and ``N_b`` in ``cands_b (M, 2)`` (each robot's
    legal space S_i, e.g. nodes of its path) maximizing ``min(A_a, A_b)``, the smaller of the two
    robots' unblocked scan angles of the shared ``feature``, among pairs at least ``min_separation``
    apart. Values within ``resolution`` of the best tie; then the smallest ``cost (K, M)`` (e.g. the
    displacement from the old subgoals) wins."""
    pa, pb = np.atleast_2d(np.asarray(cands_a, dtype=float)), np.atleast_2d(np.asarray(cands_b, dtype=float))
    if len(pa) == 0 or len(pb) == 0:
        return PairChoice(-1, -1, -math.inf)
    args = (robot_radius, range_max, incidence_max, cone)
    worst = np.minimum(unblocked_angles(pa, feature, pb, *args, resolution=resolution),
                       unblocked_angles(pb, feature, pa, *args, resolution=resolution).T)
    apart = np.hypot(pa[:, None, 0] - pb[None, :, 0], pa[:, None, 1] - pb[None, :, 1]) >= min_separation
    worst = np.where(apart, worst, -math.inf)
    top = float(worst.max())
    if not np.isfinite(top):
        return PairChoice(-1, -1, -math.inf)
    c = np.zeros(worst.shape) if cost is None else np.asarray(cost, dtype=float)
    a, b = np.unravel_index(int(np.argmin(np.where(worst >= top - resolution / 2, c, np.inf))), worst.shape)
    return PairChoice(int(a), int(b), float(worst[a, b]))


@dataclass(frozen=True)
class Rearrangement:
    """Result of :func:`bisector_rearrangement`."""

    subgoals: np.ndarray
    """(2, 2) new subgoals."""
    on_path: tuple[bool, bool]
    """Per robot: its path crosses the bisector and its subgoal moved to the crossing."""
    bisector: tuple[np.ndarray, np.ndarray]
    """A point of the bisector (midpoint of c-F) and its unit direction."""


def _path_crossing(path: PathNodes, m: np.ndarray, n: np.ndarray, near: float,
                   window: tuple[float, float] = (-math.inf, math.inf)) -> np.ndarray | None:
    """Crossing of ``path`` with the line ``(x - m) . n = 0`` nearest arclength ``near`` among those
    at arclengths within ``window``, or None."""
    d = (path.xy - m) @ n
    idx = np.nonzero(np.sign(d[:-1]) * np.sign(d[1:]) <= 0)[0]
    if len(idx) == 0:
        return None
    t = np.where(np.abs(d[idx] - d[idx + 1]) > 1e-12, d[idx] / (d[idx] - d[idx + 1] + 1e-300), 0.0)
    sig = path.s[idx] + t * (path.s[idx + 1] - path.s[idx])
    ok = (sig >= window[0] - 1e-9) & (sig <= window[1] + 1e-9)
    if not ok.any():
        return None
    k = int(np.argmin(np.where(ok, np.abs(sig - near), np.inf)))
    return path.xy[idx[k]] + t[k] * (path.xy[idx[k] + 1] - path.xy[idx[k]])


def bisector_rearrangement(subgoals, paths: list[PathNodes], sigmas, feature_point, min_separation: float,
                           free=None, max_slide: float = 3.0, slide_step: float = 0.02,
                           windows: list[tuple[float, float]] | None = None) -> Rearrangement:
    """Kim, Pearce & Amato §4: rearrange the subgoals of two robots sharing a sector so both can scan the feature.

    ``subgoals (2, 2)`` the current subgoals on ``paths`` at arclengths ``sigmas``; ``feature_point``
    the corner both localize on; ``free(points) -> bool array`` optional free-space test for the
    off-path point (e.g. the map eroded by the robot radius); ``windows`` optional per-path arclength
    interval where a crossing counts (e.g. ahead of the robot, within its horizon). See the module
    docstring.
    """
    sub = np.asarray(subgoals, dtype=float).reshape(2, 2)
    f = np.asarray(feature_point, dtype=float)
    c = sub.mean(axis=0)
    axis = f - c
    if not np.hypot(*axis) > 1e-9:
        raise ValueError("the robots' centre coincides with the feature")
    n = axis / np.hypot(*axis)
    m = 0.5 * (c + f)
    u = np.array([-n[1], n[0]])
    wins = windows if windows is not None else [(-math.inf, math.inf)] * 2
    hits = [_path_crossing(p, m, n, float(s), w) for p, s, w in zip(paths, sigmas, wins, strict=True)]
    on_path = [h is not None for h in hits]
    out = np.array([h if h is not None else p - ((p - m) @ n) * n for h, p in zip(hits, sub, strict=True)])
    if np.hypot(*(out[1] - out[0])) < min_separation:
        # slide an off-path robot (else the second) along the bisector, away from the other one
        k = 1 if not on_path[1] or on_path[0] else 0
        j = 1 - k
        side = np.sign((out[k] - out[j]) @ u) or np.sign((sub[k] - sub[j]) @ u) or 1.0
        base = out[k].copy()
        found = False
        for step in range(1, int(max_slide / slide_step) + 1):
            for sgn in (side, -side):  # away from the other robot first, else past it
                cand = base + sgn * step * slide_step * u
                if np.hypot(*(cand - out[j])) >= min_separation and (free is None or bool(free(cand[None])[0])):
                    out[k], on_path[k], found = cand, False, True
                    break
            if found:
                break
    return Rearrangement(out, (bool(on_path[0]), bool(on_path[1])), (m, u))
