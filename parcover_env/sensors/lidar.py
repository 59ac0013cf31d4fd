"""2-D lidar (VMAS-like): ``n_rays`` rays evenly over 360 degrees from each robot's centre.

Ray ``i`` of a robot at ``(x, y, theta)`` leaves the centre at angle ``theta + 2 pi i / n_rays``
and reads the distance to the first wall segment or other robot's disc of its world (the robot's
own disc is ignored), plus Gaussian noise of ``noise_std`` (m), clipped to ``[0, range_max]``; a
ray that hits nothing within ``range_max`` reads ``range_max`` exactly. Casting goes through the
public ray kernel (:func:`~parcover_env.geometry.cast_rays`,
:func:`~parcover_env.geometry.cast_rays_discs`), every robot of every world in one call each.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from parcover_env.config.robot import LidarConfig
from parcover_env.geometry import cast_rays, cast_rays_discs
from parcover_env.sensors.base import SensingState

__all__ = ["Lidar"]


class Lidar:
    """A :class:`~parcover_env.sensors.base.Sensor`: ranges ``(K, N, n_rays)`` float32 (m)."""

    def __init__(self, cfg: LidarConfig):
        self.cfg = cfg
        self.angles = np.arange(cfg.n_rays) * (2 * np.pi / cfg.n_rays)
        """Robot-frame angle of each ray (rad)."""

    @property
    def size(self) -> int:
        return self.cfg.n_rays

    def ideal(self, state: SensingState) -> np.ndarray:
        """Noise-free ranges ``(K, N, n_rays)`` (m): ``inf`` where nothing lies within ``range_max``."""
        k, n = state.n_worlds, state.n_robots
        flat = state.poses.reshape(k * n, 3)
        axes = flat[:, 2:3] + self.angles[None, :]
        directions = np.stack([np.cos(axes), np.sin(axes)], axis=-1)
        r_max = self.cfg.range_max
        walls = cast_rays(flat[:, :2], directions, state.segments, r_max).distance
        centres = np.broadcast_to(state.poses[:, None, :, :2], (k, n, n, 2)).reshape(k * n, n, 2)
        robots = cast_rays_discs(flat[:, :2], directions, centres, state.robot_radius, np.tile(np.arange(n), k), r_max)
        return np.minimum(walls, robots).reshape(k, n, self.size)

    def sense(self, state: SensingState, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """Readings ``(K, N, n_rays)`` float32; world ``k`` draws its ``N x n_rays`` normals from ``rngs[k]``."""
        d = self.ideal(state)
        r_max, sigma = self.cfg.range_max, self.cfg.noise_std
        if sigma > 0:
            z = np.stack([rng.standard_normal((state.n_robots, self.size)) for rng in rngs])
            d = np.where(np.isfinite(d), np.clip(d + sigma * z, 0.0, r_max), d)
        return np.where(np.isfinite(d), d, r_max).astype(np.float32)

    def ray_ends(self, poses: np.ndarray, ranges: np.ndarray) -> np.ndarray:
        """For drawing: the end point ``(..., n_rays, 2)`` of each ray of ``poses (..., 3)`` at ``ranges``."""
        axes = poses[..., 2:3] + self.angles
        return np.stack([poses[..., 0:1] + ranges * np.cos(axes), poses[..., 1:2] + ranges * np.sin(axes)], axis=-1)
