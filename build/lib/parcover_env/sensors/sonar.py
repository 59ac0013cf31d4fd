"""Sonar ring model (seed B): ranges per beam for all robots in one vectorized numpy pass.

Geometry and conventions
- The transducers sit at the robot centre (a documented simplification: ranges are measured from
  the centre, so a wall touching the robot reads ``robot_radius``). Beam angles are in the robot
  frame, counter-clockwise from the heading.
- ``model: ray`` — one ideal ray along each beam axis; reading = first hit (walls or other robots).
- ``model: specular`` — each beam is a cone of ``cone_deg`` sampled by ``n_subrays`` rays. A sub-ray
  echoes from a wall only when it meets the wall within ``incidence_max_deg`` of the normal (else the
  energy is reflected away: no echo from that sub-ray); other robots (cylinders) always echo; a
  concave corner (two walls meeting at < 180 deg, seen from inside their wedge) inside the cone and in
  line of sight retro-reflects at the corner distance. The reading is the nearest echo in the cone.
- No echo, or an echo beyond ``range_max``, reads ``range_max`` ("too far", the paper's 2.54 m).
  Echoes get noise ``N(0, (noise_std + noise_rel * r)^2)``, are quantized to ``quantization`` and
  clamped to ``[range_min, range_max]``. ``garbage_rate`` replaces readings by uniform random ranges.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from parcover_env.config import SonarConfig
from parcover_env.geometry import point_segment_distance, wrap_angle

__all__ = ["SonarRing", "AMIGOBOT_ANGLES_DEG", "concave_corners", "simulate_beams"]

AMIGOBOT_ANGLES_DEG = (90.0, 44.0, 12.0, -12.0, -44.0, -90.0, -144.0, 144.0)
"""AmigoBot sonar layout (robot frame, deg): six forward-facing transducers and two rear ones."""

_EPS = 1e-9
_NEAR_MIN_RAYS = 32
"""Rays per robot from which the range-culled ray casting (``_ray_segments_near``) is used ..."""
_NEAR_MIN_WORK = 50_000
"""... when rays x segments (or discs) reach this: below, its set-up costs more than it saves."""


@lru_cache(maxsize=32)
def _corner_table(seg_bytes: bytes, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    segs = np.frombuffer(seg_bytes, dtype=float).reshape(n, 4)
    ends: dict[tuple[float, float], list[np.ndarray]] = {}
    for x1, y1, x2, y2 in segs:
        a, b = (round(x1, 9), round(y1, 9)), (round(x2, 9), round(y2, 9))
        if a == b:
            continue
        ends.setdefault(a, []).append(np.array(b))
        ends.setdefault(b, []).append(np.array(a))
    pts, u1s, u2s = [], [], []
    for v, others in ends.items():
        if len(others) != 2:
            continue
        vv = np.array(v)
        u1, u2 = others[0] - vv, others[1] - vv
        u1, u2 = u1 / np.linalg.norm(u1), u2 / np.linalg.norm(u2)
        if abs(u1[0] * u2[1] - u1[1] * u2[0]) < 1e-9:  # collinear: not a corner
            continue
        pts.append(vv)
        u1s.append(u1)
        u2s.append(u2)
    if not pts:
        z = np.zeros((0, 2))
        return z, z, z
    return np.array(pts), np.array(u1s), np.array(u2s)


def concave_corners(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices shared by exactly two non-collinear segments: ``(points (C,2), u1 (C,2), u2 (C,2))``
    with ``u1, u2`` the unit wall directions leaving the vertex. Whether a vertex is concave depends
    on the viewpoint; see :func:`_corner_faces`. Cached per segment array contents."""
    seg = np.ascontiguousarray(segments, dtype=float)
    return _corner_table(seg.tobytes(), len(seg))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _corner_faces(origins: np.ndarray, pts: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """``(N, C)``: whether each origin lies strictly inside the < 180 deg wedge of each corner."""
    v = origins[:, None, :] - pts[None, :, :]
    s = _cross(u1, u2)[None, :]
    return (_cross(u1[None], v) * s > 0) & (_cross(v, u2[None]) * s > 0)


def _ray_segments(origins, dirs, segments, with_cos: bool = True):
    """Nearest hit per ray: ``(t (R,), seg index (R,), |cos incidence| (R,) or None)`` (t = inf if
    none). Works on contiguous ``(R, S)`` planes (one per coordinate): no ``(R, S, 2)`` temporaries."""
    ax, ay = segments[:, 0], segments[:, 1]
    ex, ey = segments[:, 2] - ax, segments[:, 3] - ay
    ox, oy = origins[:, 0:1], origins[:, 1:2]
    dx, dy = dirs[:, 0:1], dirs[:, 1:2]
    den = dx * ey - dy * ex
    wx, wy = ax - ox, ay - oy
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / den
        u = (wx * dy - wy * dx) / den
    ok = (t >= 0.0) & (u >= -1e-12) & (u <= 1.0 + 1e-12) & (np.abs(den) > 1e-12)
    t = np.where(ok, t, np.inf)
    idx = np.argmin(t, axis=1)
    rows = np.arange(len(origins))
    tmin = t[rows, idx]
    if not with_cos:
        return tmin, idx, None
    elen = np.hypot(ex, ey)
    cos_inc = np.abs(den[rows, idx]) / np.maximum(elen[idx], _EPS)  # |d x e| / |e| = |cos(incidence)|
    return tmin, idx, cos_inc


def _ray_segments_near(origins, dirs, segments, reach: float, with_cos: bool = True):
    """:func:`_ray_segments` for ``M`` rays from each of ``N`` origins (``dirs (N, M, 2)``), testing
    each origin's rays only against the segments within ``reach`` of it. Hits nearer than ``reach``
    are exactly those of the full test (a segment hit at ``t`` lies within ``t`` of the origin);
    farther hits may be missed (inf), which callers clamp to ``reach`` anyway. Returns flat
    ``(N * M,)`` arrays like :func:`_ray_segments`."""
    n, m = dirs.shape[:2]
    near = point_segment_distance(origins, segments) <= reach + 1e-6
    width = int(near.sum(axis=1).max()) if n else 0
    if width == 0:
        return np.full(n * m, np.inf), np.zeros(n * m, dtype=np.int64), np.ones(n * m)
    order = np.argsort(~near, axis=1, kind="stable")[:, :width]  # near segments first, in index order
    keep = np.take_along_axis(near, order, axis=1)[:, None, :]
    seg = segments[order]  # (N, W, 4)
    ax, ay = seg[:, None, :, 0], seg[:, None, :, 1]
    ex, ey = seg[:, None, :, 2] - ax, seg[:, None, :, 3] - ay
    dx, dy = dirs[:, :, 0:1], dirs[:, :, 1:2]
    den = dx * ey - dy * ex  # (N, M, W)
    wx, wy = ax - origins[:, None, None, 0], ay - origins[:, None, None, 1]  # (N, 1, W)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / den
        u = (wx * dy - wy * dx) / den
    ok = (t >= 0.0) & (u >= -1e-12) & (u <= 1.0 + 1e-12) & (np.abs(den) > 1e-12) & keep
    t = np.where(ok, t, np.inf)
    j = np.argmin(t, axis=2)[..., None]
    tmin = np.take_along_axis(t, j, axis=2).ravel()
    idx = np.take_along_axis(order[:, None, :], j, axis=2).ravel()
    if not with_cos:
        return tmin, idx, None
    elen = np.hypot(ex, ey)
    cos_inc = (np.abs(np.take_along_axis(den, j, axis=2))
               / np.maximum(np.take_along_axis(np.broadcast_to(elen, den.shape), j, axis=2), _EPS)).ravel()
    return tmin, idx, cos_inc


def _ray_discs(origins, dirs, centres, radius, owner):
    """First hit distance of each ray on discs (inf if none); ``owner (R,)`` disc to ignore or -1."""
    if len(centres) == 0:
        return np.full(len(origins), np.inf)
    ocx = origins[:, 0:1] - centres[None, :, 0]
    ocy = origins[:, 1:2] - centres[None, :, 1]
    b = ocx * dirs[:, 0:1] + ocy * dirs[:, 1:2]
    c = (ocx * ocx + ocy * ocy) - radius * radius
    disc = b * b - c
    t_near = -b - np.sqrt(np.maximum(disc, 0.0))
    t = np.where(c <= 0.0, 0.0, t_near)
    ok = (disc >= 0.0) & ((c <= 0.0) | (t_near >= 0.0))
    ok &= np.arange(len(centres))[None, :] != owner[:, None]
    return np.where(ok, t, np.inf).min(axis=1)


def _ray_discs_near(origins, dirs, centres, radius, owner, reach: float):
    """:func:`_ray_discs` for ``M`` rays from each of ``N`` origins (``dirs (N, M, 2)``, ``owner (N,)``),
    testing only the discs within ``reach`` of each origin (a farther disc is hit beyond ``reach``,
    which callers clamp). Returns ``(N * M,)`` distances (inf if none)."""
    n, m = dirs.shape[:2]
    ocx = origins[:, 0:1] - centres[None, :, 0]  # (N, D): the same for all rays of one origin
    ocy = origins[:, 1:2] - centres[None, :, 1]
    c_all = (ocx * ocx + ocy * ocy) - radius * radius
    near = np.hypot(ocx, ocy) <= reach + radius + 1e-6
    near &= np.arange(len(centres))[None, :] != owner[:, None]
    width = int(near.sum(axis=1).max()) if n else 0
    if width == 0:
        return np.full(n * m, np.inf)
    order = np.argsort(~near, axis=1, kind="stable")[:, :width]
    keep = np.take_along_axis(near, order, axis=1)[:, None, :]
    ocx = np.take_along_axis(ocx, order, axis=1)[:, None, :]
    ocy = np.take_along_axis(ocy, order, axis=1)[:, None, :]
    c = np.take_along_axis(c_all, order, axis=1)[:, None, :]
    b = ocx * dirs[:, :, 0:1] + ocy * dirs[:, :, 1:2]  # (N, M, W)
    disc = b * b - c
    t_near = -b - np.sqrt(np.maximum(disc, 0.0))
    t = np.where(c <= 0.0, 0.0, t_near)
    ok = (disc >= 0.0) & ((c <= 0.0) | (t_near >= 0.0)) & keep
    return np.where(ok, t, np.inf).min(axis=2).ravel()


def simulate_beams(cfg: SonarConfig, origins: np.ndarray, axes: np.ndarray, segments: np.ndarray,
                   centres: np.ndarray, radius: float, owner: np.ndarray, n_subrays: int = 5) -> np.ndarray:
    """Noise-free readings ``(N, B)`` for beams with world axis angles ``axes (N, B)`` from
    ``origins (N, 2)``; discs ``centres (D, 2)`` of ``radius`` block and echo (``owner (N,)`` = own
    disc index or -1). Values beyond ``range_max`` (no echo) read ``range_max``."""
    n, b = axes.shape
    rmax = float(cfg.range_max)
    specular = cfg.model == "specular"
    offsets = (np.linspace(-0.5, 0.5, n_subrays) * math.radians(cfg.cone_deg)) if specular else np.zeros(1)
    k = len(offsets)
    ang = (axes[:, :, None] + offsets[None, None, :]).reshape(-1)
    dirs = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    out = np.full(n * b * k, np.inf)
    # many rays per robot: test each robot's rays only against the walls and discs within range
    # (same readings; pays off from a few dozen rays per robot, e.g. 72-beam or specular scans)
    near_only = b * k >= _NEAR_MIN_RAYS and n * b * k * max(len(segments), len(centres)) >= _NEAR_MIN_WORK
    if len(segments):
        if near_only:
            out, _, cos_inc = _ray_segments_near(origins, dirs.reshape(n, b * k, 2), segments, rmax,
                                                 with_cos=specular)
        else:
            out, _, cos_inc = _ray_segments(np.repeat(origins, b * k, axis=0), dirs, segments,
                                            with_cos=specular)
    if len(centres):
        if near_only:
            t_disc = _ray_discs_near(origins, dirs.reshape(n, b * k, 2), centres, float(radius), owner, rmax)
        else:
            t_disc = _ray_discs(np.repeat(origins, b * k, axis=0), dirs, centres, float(radius),
                                np.repeat(owner, b * k))
    else:
        t_disc = out * np.inf
    if specular and len(segments):
        # an oblique wall reflects the sub-ray away; a disc in front of it still echoes
        valid = cos_inc >= math.cos(math.radians(cfg.incidence_max_deg)) - 1e-12
        out = np.where(t_disc < out, t_disc, np.where(valid, out, np.inf))
    else:
        out = np.minimum(out, t_disc)
    reading = out.reshape(n, b, k).min(axis=2)
    if specular and len(segments):
        pts, u1, u2 = concave_corners(segments)
        if len(pts):
            reading = np.minimum(reading, _corner_echoes(cfg, origins, axes, segments, centres, radius,
                                                         owner, pts, u1, u2))
    return np.minimum(reading, rmax)


def _corner_echoes(cfg, origins, axes, segments, centres, radius, owner, pts, u1, u2) -> np.ndarray:
    """``(N, B)`` nearest concave-corner echo inside each beam's cone (inf if none)."""
    vec = pts[None, :, :] - origins[:, None, :]
    dist = np.linalg.norm(vec, axis=-1)
    cand = (dist <= cfg.range_max) & (dist > _EPS) & _corner_faces(origins, pts, u1, u2)
    if not cand.any():
        return np.full(axes.shape, np.inf)
    ni, ci = np.nonzero(cand)
    d = vec[ni, ci] / dist[ni, ci, None]
    t, _, _ = _ray_segments(origins[ni], d, segments, with_cos=False)
    visible = t >= dist[ni, ci] * (1.0 - 1e-7) - 1e-9
    if len(centres):
        visible &= _ray_discs(origins[ni], d, centres, float(radius), owner[ni]) >= dist[ni, ci]
    vi, vc = ni[visible], ci[visible]
    out = np.full(axes.shape, np.inf)
    if len(vi) == 0:
        return out
    # only the visible (origin, corner) pairs: the bearing of each against every beam axis
    bearing = np.arctan2(vec[vi, vc, 1], vec[vi, vc, 0])
    diff = np.abs(wrap_angle(bearing[:, None] - axes[vi]))
    in_cone = diff <= math.radians(cfg.cone_deg) / 2 + 1e-12
    np.minimum.at(out, vi, np.where(in_cone, dist[vi, vc][:, None], np.inf))
    return out


class SonarRing:
    """A ring of sonar transducers (``cfg.layout``) plus the rotating 360-degree scan mode."""

    def __init__(self, cfg: SonarConfig, n_subrays: int = 5):
        if not isinstance(cfg, SonarConfig):
            raise ValueError(f"SonarRing needs a SonarConfig, got {type(cfg).__name__}")
        if n_subrays < 1:
            raise ValueError(f"n_subrays must be >= 1, got {n_subrays}")
        self.cfg = cfg
        self.n_subrays = int(n_subrays)
        if cfg.layout == "amigobot":
            self.beam_angles = np.radians(np.array(AMIGOBOT_ANGLES_DEG))
        else:
            self.beam_angles = np.arange(cfg.n_beams) * (2 * math.pi / cfg.n_beams)
        n_scan = round(360.0 / cfg.scan_step_deg)
        self.scan_angles = np.radians(np.arange(n_scan) * cfg.scan_step_deg)
        """Robot-frame angles of the 360-degree scan (72 readings at 5 deg)."""

    @property
    def n_beams(self) -> int:
        return len(self.beam_angles)

    def measure(self, poses, segments, robot_radius: float, rng: np.random.Generator | None,
                include_robots: bool = True) -> np.ndarray:
        """Ring readings ``(N, B)`` float32 for all robots ``poses (N, 3)`` at once. Other robots are
        discs of ``robot_radius`` that block and echo (``include_robots``). ``rng=None``: noise-free."""
        poses = _as_array(poses, "poses", (-1, 3))
        segments = _as_array(segments, "segments", (-1, 4))
        axes = poses[:, 2:3] + self.beam_angles[None, :]
        n = len(poses)
        centres = poses[:, :2] if include_robots else np.zeros((0, 2))
        owner = np.arange(n) if include_robots else np.full(n, -1)
        ideal = simulate_beams(self.cfg, poses[:, :2], axes, segments, centres, robot_radius, owner,
                               self.n_subrays)
        return self.corrupt(ideal, rng).astype(np.float32)

    def scan(self, pose, segments, other_robot_centres, robot_radius: float,
             rng: np.random.Generator | None) -> np.ndarray:
        """360-degree scan ``(len(scan_angles),)`` from ``pose (3,)`` (the paper's rotate-in-place
        mode: one beam every ``scan_step_deg``). ``rng=None`` gives the noise-free synthetic scan."""
        pose = _as_array(pose, "pose", (3,))
        segments = _as_array(segments, "segments", (-1, 4))
        others = np.zeros((0, 2)) if other_robot_centres is None else \
            _as_array(other_robot_centres, "other_robot_centres", (-1, 2))
        axes = (pose[2] + self.scan_angles)[None, :]
        ideal = simulate_beams(self.cfg, pose[None, :2], axes, segments, others, robot_radius,
                               np.array([-1]), self.n_subrays)[0]
        return self.corrupt(ideal, rng)

    def corrupt(self, ideal: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        """Noise, quantization, clamping and garbage readings applied to noise-free ranges."""
        cfg = self.cfg
        r = np.asarray(ideal, dtype=float)
        echo = r < cfg.range_max
        if rng is not None and (cfg.noise_std > 0 or cfg.noise_rel > 0):
            sigma = cfg.noise_std + cfg.noise_rel * r
            r = np.where(echo, r + sigma * rng.standard_normal(r.shape), r)
        if cfg.quantization > 0:
            r = np.where(echo, np.round(r / cfg.quantization) * cfg.quantization, r)
        r = np.clip(r, cfg.range_min, cfg.range_max)
        if rng is not None and cfg.garbage_rate > 0:
            bad = rng.random(r.shape) < cfg.garbage_rate
            r = np.where(bad, rng.uniform(cfg.range_min, cfg.range_max, r.shape), r)
        return r


def _as_array(x, name: str, shape: tuple[int, ...]) -> np.ndarray:
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numeric, got {type(x).__name__}") from None
    if shape[0] == -1 and a.ndim == 1 and a.size == shape[1] and name != "segments":
        a = a[None, :]
    if shape[0] == -1 and a.size == 0:
        return a.reshape(0, shape[1])
    if a.ndim != len(shape) or any(s not in (-1, d) for s, d in zip(shape, a.shape, strict=True)):
        want = "(N, " + ", ".join(str(s) for s in shape[1:]) + ")" if shape[0] == -1 else str(shape)
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return a
