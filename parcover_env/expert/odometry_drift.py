"""The expert's online calibration of each robot's odometry heading drift (our extension, issue 42).

The realistic wheel odometry (:mod:`parcover_env.sensors.odometry`) has per-robot systematic errors the
robot cannot know: with a right/left wheel-diameter ratio ``E_d`` the odometry's heading drifts by about
``-(E_d - 1) / b`` rad per metre driven (``b`` the wheel base; 1.2 deg/m at ``E_d - 1`` = 0.004, twice
the configured std), and each turn is read ``E_b`` times its true angle. Traced on the expert's failures
(generated:77, 7018, 7061, 7164, 18: ``E_d - 1`` of 0.0034-0.0053, 1.7-2.7 std), this drift, not the
turns, made their headings 10-35 deg wrong after 10-25 m without a fix.

Each absolute heading the expert gets measures the odometry's heading error accumulated since the
odometry was last reset (the episode's start, or an env fix, where the env's estimate jumps to the fix):
an env fix (the estimate's heading just before it against the fix), and a follower's heading chained to
the robot ahead by its camera. The error is modelled as ``e = kappa D + beta T`` plus noise, ``D`` and
``T`` the signed distance and turn the odometry measured since that reset; a Kalman filter on
``(kappa, beta)`` starts from the odometry error model's prior (stds ``diameter_ratio_std / b`` and
``wheelbase_std``) and takes each measurement with the variance of the reference heading, of the heading
at the reset, and of the wheels' random error over the distance (``wheel_variance``). The calibrated
odometry integrates the odometry's increments with each heading increment reduced by
``kappa ds + beta dtheta``; it restarts from the env's estimate at every fix.
"""

from __future__ import annotations

import math

import numpy as np

from parcover_env.config import OdometryConfig
from parcover_env.geometry import wrap_angle

__all__ = ["DriftCalibration"]


class DriftCalibration:
    """Per-robot heading drift estimates and calibrated odometry poses for ``n`` robots."""

    def __init__(self, n: int, odometry: OdometryConfig, wheel_base: float, spacing: float = 2.0):
        if not (n >= 1 and wheel_base > 0 and spacing > 0):
            raise ValueError(f"need n >= 1, wheel_base > 0 and spacing > 0, got {n}, {wheel_base}, {spacing}")
        self.prior = np.diag([(odometry.diameter_ratio_std / wheel_base) ** 2, odometry.wheelbase_std**2])
        """Prior covariance of ``(kappa (rad/m), beta (-))``."""
        self.walk = 2.0 * odometry.wheel_variance / wheel_base**2
        """Heading variance of the wheels' random error per metre driven (rad^2/m)."""
        self.spacing = float(spacing)
        """A follower's chained heading is taken as a measurement once per this many metres driven (m)."""
        self.mean = np.zeros((n, 2))
        self.cov = np.repeat(self.prior[None], n, axis=0)
        self.raw = np.full((n, 3), np.nan)
        """The odometry pose (the env's estimate) at the last step."""
        self.cal = np.full((n, 3), np.nan)
        """The calibrated odometry pose at the last step."""
        self.since = np.zeros((n, 3))
        """Since the odometry's last reset: signed distance D (m), signed turn T (rad), distance driven (m)."""
        self.reset_var = np.zeros(n)
        """Variance of the odometry's heading error at its last reset (rad^2; 0 at the episode's start)."""
        self.unmeasured = np.zeros(n)
        """Distance driven since the last measurement (m)."""

    def step(self, i: int, raw: np.ndarray, fresh: bool, fix_var: float) -> np.ndarray:
        """Robot ``i``'s calibrated pose (x, y, theta) for its odometry pose ``raw`` at this step. ``fresh``:
        ``raw`` is an absolute fix (the odometry was reset to it; its heading variance ``fix_var``): the
        heading error of the pose before it is a measurement, and the calibrated pose restarts at ``raw``."""
        raw = np.asarray(raw, dtype=float)
        if fresh or not np.isfinite(self.raw[i, 0]):
            if fresh and np.isfinite(self.raw[i, 0]) and self.since[i, 2] > 0:
                self.measure(i, float(self.raw[i, 2]), float(raw[2]), fix_var)
            self.since[i], self.reset_var[i], self.unmeasured[i] = 0.0, fix_var if fresh else 0.0, 0.0
            self.raw[i], self.cal[i] = raw, raw
            return raw.copy()
        prev = self.raw[i]
        dth = float(wrap_angle(raw[2] - prev[2]))
        mid = prev[2] + 0.5 * dth
        ds = float((raw[0] - prev[0]) * math.cos(mid) + (raw[1] - prev[1]) * math.sin(mid))
        self.since[i] += (ds, dth, abs(ds))
        self.unmeasured[i] += abs(ds)
        kappa, beta = self.mean[i]
        turn = dth - (kappa * ds + beta * dth)
        cal = self.cal[i].copy()
        mid = cal[2] + 0.5 * turn
        cal[0] += ds * math.cos(mid)
        cal[1] += ds * math.sin(mid)
        cal[2] = float(wrap_angle(cal[2] + turn))
        self.raw[i], self.cal[i] = raw, cal
        return cal.copy()

    def due(self, i: int) -> bool:
        """Whether robot ``i`` has driven ``spacing`` since its last measurement (a chained heading is taken then)."""
        return bool(self.unmeasured[i] >= self.spacing)

    def measure(self, i: int, raw_heading: float, ref_heading: float, ref_var: float) -> None:
        """Kalman update of robot ``i``'s ``(kappa, beta)`` with its odometry heading ``raw_heading`` against
        an absolute heading ``ref_heading`` of variance ``ref_var`` (rad, rad^2), since the odometry's last
        reset (:attr:`since`)."""
        d, t, driven = self.since[i]
        h = np.array([d, t])
        error = float(wrap_angle(raw_heading - ref_heading))
        p = self.cov[i]
        s = float(h @ p @ h) + ref_var + self.reset_var[i] + self.walk * driven
        if s <= 0:
            return
        gain = p @ h / s
        self.mean[i] += gain * (error - float(h @ self.mean[i]))
        cov = p - np.outer(gain, h @ p)
        self.cov[i] = 0.5 * (cov + cov.T)
        self.unmeasured[i] = 0.0
