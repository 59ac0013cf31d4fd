"""Pinhole camera geometry of an overhead Kinect: intrinsics, extrinsics, footprint.

Camera frame: x right, y down (image rows), z forward along the optical axis.
World frame: x, y on the floor, z up (m). Pixels exist only inside the Kinect model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from shapely.geometry import Polygon

__all__ = ["CameraModel"]


@dataclass(frozen=True, eq=False)
class CameraModel:
    """Intrinsics ``K`` and extrinsics (``R`` world->camera rotation, centre ``C``)."""

    width: int
    height: int
    K: np.ndarray
    R: np.ndarray
    C: np.ndarray
    range_min: float
    range_max: float

    @classmethod
    def from_config(cls, cfg: Any) -> CameraModel:
        """From a ``parcover_env.config.KinectConfig`` (read by attribute: geometry sits below config)."""
        return cls.from_pose(cfg.position, cfg.height, cfg.pitch_deg, cfg.yaw_deg, cfg.resolution,
                             cfg.fov_deg, cfg.range_min, cfg.range_max)

    @classmethod
    def from_pose(cls, position, height: float, pitch_deg: float, yaw_deg: float,
                  resolution=(640, 480), fov_deg=(57.0, 43.0), range_min: float = 0.8,
                  range_max: float = 4.0) -> CameraModel:
        """Pitch: tilt below horizontal (90 = down). Yaw: floor direction of the image top/forward."""
        w, h = int(resolution[0]), int(resolution[1])
        fx = (w / 2) / math.tan(math.radians(fov_deg[0]) / 2)
        fy = (h / 2) / math.tan(math.radians(fov_deg[1]) / 2)
        K = np.array([[fx, 0.0, w / 2 - 0.5], [0.0, fy, h / 2 - 0.5], [0.0, 0.0, 1.0]])
        p, y = math.radians(pitch_deg), math.radians(yaw_deg)
        forward = np.array([math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), -math.sin(p)])
        right = np.array([math.sin(y), -math.cos(y), 0.0])
        down = np.cross(forward, right)
        R = np.stack([right, down, forward])
        C = np.array([position[0], position[1], height], dtype=float)
        return cls(w, h, K, R, C, float(range_min), float(range_max))

    def perturbed(self, d_pitch: float, d_roll: float, d_yaw: float, d_height: float) -> CameraModel:
        """The same camera mounted slightly off: rotated by ``d_pitch`` about its x axis (image
        right), ``d_roll`` about its y axis (image down) and ``d_yaw`` about its optical axis (rad),
        and raised by ``d_height`` (m). Intrinsics unchanged."""
        def rot(axis: int, a: float) -> np.ndarray:
            c, s = math.cos(a), math.sin(a)
            i, j = [k for k in range(3) if k != axis]
            q = np.eye(3)
            q[i, i], q[i, j], q[j, i], q[j, j] = c, -s, s, c
            return q

        q = rot(0, d_pitch) @ rot(1, d_roll) @ rot(2, d_yaw)  # body rotation in the camera frame
        return CameraModel(self.width, self.height, self.K, q.T @ self.R, self.C + np.array([0.0, 0.0, d_height]),
                           self.range_min, self.range_max)

    @property
    def focal(self) -> float:
        return float(self.K[0, 0])

    def project(self, points_w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points ``(N, 3)`` -> pixel coordinates ``(N, 2)`` (u, v) and depth ``z (N,)``."""
        pc = (np.asarray(points_w, dtype=float) - self.C) @ self.R.T
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = (pc[:, :2] / z[:, None]) * np.diag(self.K)[:2] + self.K[:2, 2]
        return uv, z

    def pixel_rays(self, uv: np.ndarray) -> np.ndarray:
        """World-frame ray directions ``(N, 3)`` (camera z component = 1) through pixels ``(N, 2)``."""
        uv = np.asarray(uv, dtype=float)
        xc = (uv[:, 0] - self.K[0, 2]) / self.K[0, 0]
        yc = (uv[:, 1] - self.K[1, 2]) / self.K[1, 1]
        return np.stack([xc, yc, np.ones_like(xc)], axis=1) @ self.R

    def backproject(self, uv: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Pixels ``(N, 2)`` with depth (camera z, m) -> world points ``(N, 3)``."""
        return self.C + self.pixel_rays(uv) * np.asarray(depth, dtype=float)[:, None]

    def footprint(self, z: float = 0.0) -> Polygon:
        """Region of the horizontal plane at height ``z`` (m; 0 = the floor, the robots' top for
        their markers) seen by the camera with a valid depth (shapely polygon)."""
        corners = np.array([[-0.5, -0.5], [self.width - 0.5, -0.5],
                            [self.width - 0.5, self.height - 0.5], [-0.5, self.height - 0.5]])
        rays = self.pixel_rays(corners)
        h = self.C[2] - float(z)
        if np.any(rays[:, 2] >= 0) or h <= 0:
            return Polygon()
        pts = self.C[:2] + rays[:, :2] * (h / -rays[:, 2])[:, None]
        quad = Polygon(pts)
        # Valid depth band: range_min <= forward . (p - C) <= range_max, a strip on the floor.
        f = self.R[2]
        g = f[:2]
        norm = float(np.hypot(*g))
        lo = self.range_min + f[2] * h  # forward.(p - C) = g.(p - C_xy) - f_z * h
        hi = self.range_max + f[2] * h
        if norm < 1e-9:  # looking straight down: depth is the height everywhere
            return quad if self.range_min <= h <= self.range_max else Polygon()
        u = g / norm
        v = np.array([-u[1], u[0]])
        big = 1e3
        a, b = lo / norm, hi / norm
        strip = Polygon([self.C[:2] + u * s + v * t for s, t in ((a, -big), (b, -big), (b, big), (a, big))])
        return quad.intersection(strip)

    def intersect_plane(self, uv: np.ndarray, z: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Rays through pixels ``(N, 2)`` met with the horizontal plane at height ``z`` (m).

        Returns world points ``(N, 3)`` and their camera depth ``(N,)``; rays that never reach the
        plane in front of the camera get NaN points and depth ``inf``.
        """
        rays = self.pixel_rays(np.atleast_2d(np.asarray(uv, dtype=float)))
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (float(z) - self.C[2]) / rays[:, 2]
        ok = np.isfinite(t) & (t > 0)
        t = np.where(ok, t, np.inf)
        pts = np.where(ok[:, None], self.C + rays * np.where(ok, t, 0.0)[:, None], np.nan)
        return pts, t
