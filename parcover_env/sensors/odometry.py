"""Wheel odometry: dead reckoning from wheel encoders with UMBmark errors, and its covariance.

Two models (``OdometryConfig.model``):

* ``wheels`` (realistic): integrates the wheel distances the drive produced (encoder ticks), so
  contact pushes go unseen, with per-episode systematic errors (wheel-diameter ratio E_d, scale,
  wheel-base ratio E_b; Borenstein & Feng's UMBmark), per-wheel random errors of variance
  proportional to distance, and slip growing with wheel acceleration and turn rate.
* ``motion`` (ideal preset, the pre-issue-13 model): the body's true displacement along its
  heading with relative Gaussian noise per control step.

The pose covariance is propagated with Chong & Kleeman's (1997) Jacobians of the pose update with
respect to the previous pose and the step's increments, and reset at absolute fixes.
"""

from __future__ import annotations

import numpy as np

from parcover_env.config import OdometryConfig
from parcover_env.geometry import wrap_angle
from parcover_env.geometry.records import record
from parcover_env.sensors import onboard_kernels

__all__ = ["Odometry", "encoder_factors", "integrate", "propagate_covariance", "wheel_increment_cov",
           "measure_wheels_all"]


def encoder_factors(e_d: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Measured / true distance of the left and right wheels ``(N, 2)``.

    The encoders convert ticks with the nominal diameter ``D_n = (D_L + D_R) / 2``; with
    ``E_d = D_R / D_L`` and a common scale error, ``D_L = 2 D_n / (E_d + 1)`` and
    ``D_R = 2 E_d D_n / (E_d + 1)``, so a wheel's reading is its distance times ``D_n / D``.
    """
    e_d = np.asarray(e_d, dtype=float)
    s = 1.0 / np.asarray(scale, dtype=float)
    return np.stack([s * (e_d + 1.0) / 2.0, s * (e_d + 1.0) / (2.0 * e_d)], axis=-1)


def integrate(pose: np.ndarray, ds: np.ndarray, dth: np.ndarray) -> None:
    """Advance poses ``(N, 3)`` in place by ``ds`` along the mid-step heading and ``dth``."""
    mid = pose[:, 2] + 0.5 * dth
    pose[:, 0] += ds * np.cos(mid)
    pose[:, 1] += ds * np.sin(mid)
    pose[:, 2] = wrap_angle(pose[:, 2] + dth)


def wheel_increment_cov(var_left: np.ndarray, var_right: np.ndarray, wheel_base: float | np.ndarray) -> np.ndarray:
    """Covariance ``(N, 2, 2)`` of ``(ds, dtheta)`` from independent wheel-distance variances:
    ``ds = (d_L + d_R) / 2``, ``dtheta = (d_R - d_L) / b``."""
    b = np.asarray(wheel_base, dtype=float)
    q = np.empty((len(var_left), 2, 2))
    q[:, 0, 0] = 0.25 * (var_left + var_right)
    q[:, 1, 1] = (var_left + var_right) / b**2
    q[:, 0, 1] = q[:, 1, 0] = 0.5 * (var_right - var_left) / b
    return q


def propagate_covariance(cov: np.ndarray, theta: np.ndarray, ds: np.ndarray, dth: np.ndarray,
                         q: np.ndarray) -> np.ndarray:
    """One step of the pose covariance ``(N, 3, 3)`` (Chong & Kleeman 1997).

    ``theta`` is the heading before the step, ``(ds, dth)`` the step's increments and ``q``
    ``(N, 2, 2)`` their covariance: ``P' = F P F^T + G Q G^T`` with ``F = d pose' / d pose`` and
    ``G = d pose' / d (ds, dth)`` for the mid-heading update of :func:`integrate`.
    """
    n = len(theta)
    mid = theta + 0.5 * dth
    c, s = np.cos(mid), np.sin(mid)
    f = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    f[:, 0, 2] = -ds * s
    f[:, 1, 2] = ds * c
    g = np.zeros((n, 3, 2))
    g[:, 0, 0], g[:, 0, 1] = c, -0.5 * ds * s
    g[:, 1, 0], g[:, 1, 1] = s, 0.5 * ds * c
    g[:, 2, 1] = 1.0
    return f @ cov @ f.transpose(0, 2, 1) + g @ q @ g.transpose(0, 2, 1)


class Odometry:
    """Per-robot pose estimates ``estimate (N, 3)`` and covariances ``covariance (N, 3, 3)``.

    ``wheel_base`` is the robot's true effective wheel base (m). With ``model: wheels`` the
    systematic errors are drawn here, once per episode, from ``rng``.
    """

    def __init__(self, cfg: OdometryConfig, true_poses: np.ndarray, wheel_base: float = 0.18,
                 rng: np.random.Generator | None = None):
        self.cfg = cfg
        n = len(true_poses)
        self.wheel_base = float(wheel_base)
        self.wheel_errors = record(onboard_kernels.WHEEL_ERRORS, wheel_base=self.wheel_base,
                                   slip_accel=cfg.slip_accel, slip_turn=cfg.slip_turn,
                                   wheel_variance=cfg.wheel_variance,
                                   covariance_wheel_variance=cfg.covariance_wheel_variance)
        """The compiled wheels' random errors (:data:`~parcover_env.sensors.onboard_kernels.WHEEL_ERRORS`)."""
        self._last_true = np.array(true_poses, dtype=float)
        self.estimate = np.array(true_poses, dtype=float)
        self.covariance = np.zeros((n, 3, 3))
        self.travelled = np.zeros(n)
        """Distance travelled since the last absolute fix (m), per robot."""
        self.turned = np.zeros(n)
        """Absolute angle turned since the last absolute fix (rad), per robot."""
        z = np.zeros((3, n))
        if cfg.model == "wheels" and rng is not None:
            z = rng.standard_normal((3, n))
        self.set_systematic(1.0 + cfg.diameter_ratio_std * z[0], 1.0 + cfg.scale_std * z[1],
                            1.0 + cfg.wheelbase_std * z[2])

    def set_systematic(self, e_d, scale, e_b) -> None:
        """Set the systematic errors per robot (scalars or ``(N,)``): E_d = D_R / D_L, mean diameter /
        nominal, E_b = effective wheel base / nominal."""
        n = len(self.estimate)
        self.e_d = np.broadcast_to(np.asarray(e_d, dtype=float), (n,)).copy()
        self.scale = np.broadcast_to(np.asarray(scale, dtype=float), (n,)).copy()
        self.e_b = np.broadcast_to(np.asarray(e_b, dtype=float), (n,)).copy()
        self.factors = encoder_factors(self.e_d, self.scale)
        """Encoder reading / true wheel distance ``(N, 2)`` (left, right)."""
        self.believed_base = self.wheel_base / self.e_b
        """The nominal wheel base the odometry divides by (m), per robot."""

    # ------------------------------------------------------------------ motion model
    def measure(self, true_poses: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """``motion`` model: advance with the true motion since the last call (+ noise); ``(N, 3)``."""
        delta = true_poses[:, :2] - self._last_true[:, :2]
        dth = wrap_angle(true_poses[:, 2] - self._last_true[:, 2])
        # wheels measure motion along the (mid-step) heading, not lateral pushes from contacts
        mid_true = self._last_true[:, 2] + 0.5 * dth
        ds = delta[:, 0] * np.cos(mid_true) + delta[:, 1] * np.sin(mid_true)
        n = len(ds)
        ds_m = ds * (1.0 + self.cfg.noise_v * rng.standard_normal(n))
        dth_m = dth * (1.0 + self.cfg.noise_omega * rng.standard_normal(n))
        q = np.zeros((n, 2, 2))
        q[:, 0, 0] = (self.cfg.noise_v * ds_m) ** 2
        q[:, 1, 1] = (self.cfg.noise_omega * dth_m) ** 2
        self._advance(ds_m, dth_m, q)
        self._last_true[:] = true_poses
        return self.estimate

    # ------------------------------------------------------------------ wheel model
    def measure_wheels(self, travel: np.ndarray, speed_change: np.ndarray, dt: float,
                       rng: np.random.Generator) -> np.ndarray:
        """``wheels`` model: advance with the encoder readings of one control step; ``(N, 3)``.

        ``travel`` ``(N, 2)``: each wheel's true ground distance (m) over the step of ``dt`` s;
        ``speed_change`` ``(N, 2)``: the summed |speed changes| of each wheel (m/s) over it.
        """
        measure_wheels_all([self], np.asarray(travel, dtype=float)[None], np.asarray(speed_change, dtype=float)[None],
                           dt, [rng])
        return self.estimate

    def _advance(self, ds: np.ndarray, dth: np.ndarray, q: np.ndarray) -> None:
        est = self.estimate
        self.covariance[:] = propagate_covariance(self.covariance, est[:, 2], ds, dth, q)
        integrate(est, ds, dth)
        self.travelled += np.abs(ds)
        self.turned += np.abs(dth)

    def fix(self, index: int, pose, cov: np.ndarray | None = None) -> None:
        """Reset robot ``index``'s estimate to an absolute pose fix of covariance ``cov`` (3, 3)."""
        self.estimate[index] = pose
        self.covariance[index] = 0.0 if cov is None else cov
        self.travelled[index] = 0.0
        self.turned[index] = 0.0

    def set_truth(self, true_poses: np.ndarray) -> None:
        """Estimates := ``true_poses`` with zero covariance (``pose_source: ground_truth``)."""
        self.estimate[:] = true_poses
        self.covariance[:] = 0.0


def measure_wheels_all(odometries: list[Odometry], travel: np.ndarray, speed_change: np.ndarray, dt: float,
                       rngs: list[np.random.Generator]) -> np.ndarray:
    """:meth:`Odometry.measure_wheels` of ``K`` odometries of ``N`` robots each (one configuration)
    in one compiled call over all ``K N`` robots: ``travel`` and ``speed_change`` ``(K, N, 2)``.
    Odometry ``k`` draws its ``4 N`` normals from ``rngs[k]`` as alone and its estimate, covariance,
    ``travelled`` and ``turned`` arrays are updated in place (the same floats as alone). Returns the
    new estimates ``(K, N, 3)`` (a copy for ``K > 1``, a view of the odometry's own for ``K = 1``)."""
    k, n = len(odometries), len(odometries[0].estimate)
    z = np.empty((k, 4 * n))
    for row, rng in zip(z, rngs, strict=True):
        rng.standard_normal(out=row)
    travel = np.ascontiguousarray(travel, dtype=float).reshape(k * n, 2)
    change = np.ascontiguousarray(speed_change, dtype=float).reshape(k * n, 2)
    first = odometries[0]
    if k == 1:  # one odometry: its own arrays, no gather
        state = onboard_kernels.OdometryState(first.estimate, first.covariance, first.travelled, first.turned,
                                              first.factors, first.believed_base)
        onboard_kernels.wheel_odometry(state, travel, change, float(dt), z, first.wheel_errors)
        return first.estimate[None]
    est = np.concatenate([o.estimate for o in odometries])
    cov = np.concatenate([o.covariance for o in odometries])
    travelled = np.concatenate([o.travelled for o in odometries])
    turned = np.concatenate([o.turned for o in odometries])
    factors = np.concatenate([o.factors for o in odometries])
    believed = np.concatenate([o.believed_base for o in odometries])
    onboard_kernels.wheel_odometry(onboard_kernels.OdometryState(est, cov, travelled, turned, factors, believed),
                                   travel, change, float(dt), z, first.wheel_errors)
    for j, o in enumerate(odometries):
        rows = slice(j * n, (j + 1) * n)
        o.estimate[:] = est[rows]
        o.covariance[:] = cov[rows]
        o.travelled[:] = travelled[rows]
        o.turned[:] = turned[rows]
    return est.reshape(k, n, 3)
