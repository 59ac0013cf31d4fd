"""References of :mod:`parcover_env.sensors.onboard_kernels` as numpy formulas:
:func:`wheel_odometry` and :func:`camera_view`."""

from __future__ import annotations

import numpy as np


def wheel_odometry(odo, travel, speed_change, dt, rng):
    """``measure_wheels`` as numpy formulas (the reference of the compiled step); returns
    (estimate, covariance, travelled, turned) without touching ``odo``."""
    from parcover_env.sensors.odometry import integrate, propagate_covariance, wheel_increment_cov

    c, d = odo.cfg, np.asarray(travel, dtype=float)
    z = rng.standard_normal((2,) + d.shape)
    turn_rate = np.abs(d[:, 1] - d[:, 0]) / (odo.wheel_base * dt)
    slip = np.abs(z[0]) * (c.slip_accel * np.asarray(speed_change) / dt + c.slip_turn * turn_rate[:, None])
    read = d * odo.factors * (1.0 + slip) + np.sqrt(c.wheel_variance * np.abs(d)) * z[1]
    ds, dth = 0.5 * (read[:, 0] + read[:, 1]), (read[:, 1] - read[:, 0]) / odo.believed_base
    var = c.covariance_wheel_variance * np.abs(read)
    est = odo.estimate.copy()
    cov = propagate_covariance(odo.covariance, est[:, 2], ds, dth,
                               wheel_increment_cov(var[:, 0], var[:, 1], odo.believed_base))
    integrate(est, ds, dth)
    return est, cov, odo.travelled + np.abs(ds), odo.turned + np.abs(dth)


def camera_view(cam, poses, predecessor, segments, rng):
    """The camera as numpy formulas (the reference of the compiled kernel)."""
    from parcover_env.geometry import segments_blocked, wrap_angle

    n = len(poses)
    rel_xy, rel_heading, visible = np.zeros((n, 2)), np.zeros(n), np.zeros(n, dtype=bool)
    f = np.flatnonzero(predecessor >= 0)
    me, other = poses[f], poses[predecessor[f]]
    delta = other[:, :2] - me[:, :2]
    dist = np.hypot(delta[:, 0], delta[:, 1])
    bearing = wrap_angle(np.arctan2(delta[:, 1], delta[:, 0]) - me[:, 2])
    seen = (dist <= cam.max_range) & (np.abs(bearing) <= np.radians(cam.fov_deg) / 2)
    seen &= ~segments_blocked(me[:, :2], other[:, :2], segments)
    r = dist * (1.0 + cam.range_noise * rng.standard_normal(len(f)))
    b = bearing + cam.bearing_noise * rng.standard_normal(len(f))
    h = wrap_angle(other[:, 2] - me[:, 2] + cam.heading_noise * rng.standard_normal(len(f)))
    rel_xy[f] = np.where(seen[:, None], np.stack([r * np.cos(b), r * np.sin(b)], axis=1), 0.0)
    rel_heading[f] = np.where(seen, h, 0.0)
    visible[f] = seen
    return rel_xy, rel_heading, visible
