"""Wheel odometry: dead reckoning from the robots' true motion with multiplicative noise."""

from __future__ import annotations

import numpy as np

from parcover_env.config import OdometryConfig
from parcover_env.geometry import wrap_angle

__all__ = ["Odometry"]


class Odometry:
    """Integrates each robot's measured displacement into a pose estimate.

    Per control step the encoders measure the travelled distance ``ds`` and the turned angle
    ``dtheta`` with relative Gaussian errors ``noise_v`` and ``noise_omega`` (slip, wheel radius
    errors). The estimate can be reset to an absolute fix (Kinect, sonar localizer).
    """

    def __init__(self, cfg: OdometryConfig, true_poses: np.ndarray):
        self.cfg = cfg
        self._last_true = np.array(true_poses, dtype=float)
        self.estimate = np.array(true_poses, dtype=float)
        self.travelled = np.zeros(len(true_poses))
        """Distance travelled since the last absolute fix (m), per robot."""
        self.turned = np.zeros(len(true_poses))
        """Absolute angle turned since the last absolute fix (rad), per robot."""

    def measure(self, true_poses: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Advance the estimates with the motion since the last call; returns ``(N, 3)``."""
        delta = true_poses[:, :2] - self._last_true[:, :2]
        dth = wrap_angle(true_poses[:, 2] - self._last_true[:, 2])
        # wheels measure motion along the (mid-step) heading, not lateral pushes from contacts
        mid_true = self._last_true[:, 2] + 0.5 * dth
        ds = delta[:, 0] * np.cos(mid_true) + delta[:, 1] * np.sin(mid_true)
        n = len(ds)
        ds_m = ds * (1.0 + self.cfg.noise_v * rng.standard_normal(n))
        dth_m = dth * (1.0 + self.cfg.noise_omega * rng.standard_normal(n))
        est = self.estimate
        mid = est[:, 2] + 0.5 * dth_m
        est[:, 0] += ds_m * np.cos(mid)
        est[:, 1] += ds_m * np.sin(mid)
        est[:, 2] = wrap_angle(est[:, 2] + dth_m)
        self.travelled += np.abs(ds_m)
        self.turned += np.abs(dth_m)
        self._last_true[:] = true_poses
        return est

    def fix(self, index: int, pose) -> None:
        """Reset robot ``index``'s estimate to an absolute pose fix."""
        self.estimate[index] = pose
        self.travelled[index] = 0.0
        self.turned[index] = 0.0
