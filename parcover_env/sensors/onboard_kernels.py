"""Compiled (numba) loops of the onboard sensors, the internals of :mod:`parcover_env.sensors.relative`
(the follower camera) and :mod:`parcover_env.sensors.odometry` (the wheel odometry); public so that
tests and other rooms may use them (the sonar's are in :mod:`parcover_env.sensors.sonar_kernels`).
They read their constants from records (structured arrays, :mod:`parcover_env.geometry.records`):
:data:`CAMERA` and :data:`WHEEL_ERRORS`.

The callers draw the random numbers (numpy, the episode's generator, whole arrays in the order the
numpy formulas drew them) and hand them in: passing a ``Generator`` to a compiled function costs
about 5 us per call. ``tests/references/onboard.py`` keeps the numpy references.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.geometry.angle_kernels import wrap

__all__ = ["CAMERA", "WHEEL_ERRORS", "OdometryState", "camera_view", "wheel_odometry", "wheel_odometry_rows"]

CAMERA = np.dtype([
    ("max_range", "f8"),  # (m)
    ("half_fov", "f8"),  # half the field of view (rad)
    ("range_noise", "f8"),  # range sigma per metre of distance
    ("bearing_noise", "f8"),  # (rad)
    ("heading_noise", "f8"),  # (rad)
])
"""The follower camera's reach and noise (:class:`parcover_env.sensors.relative.RelativeCamera`)."""

WHEEL_ERRORS = np.dtype([
    ("wheel_base", "f8"),  # the true wheel base (m)
    ("slip_accel", "f8"),  # slip per unit of wheel acceleration (s^2 / m)
    ("slip_turn", "f8"),  # slip per unit of turn rate (s / rad)
    ("wheel_variance", "f8"),  # random per-wheel variance per metre (m)
    ("covariance_wheel_variance", "f8"),  # the variance the covariance assumes (m)
])
"""The wheels' random error model (:class:`parcover_env.config.OdometryConfig`)."""


@njit(cache=True, nogil=True)
def camera_view(px, py, pth, predecessor, blocked, z, camera, rel_xy, rel_heading, visible):
    """The follower camera (:meth:`parcover_env.sensors.relative.RelativeCamera.measure`) of robots
    ``px, py, pth (N,)``: for each follower ``i`` (``predecessor[i] >= 0``, F of them) of its
    predecessor ``j``: range ``r (1 + range_noise z1)``, bearing ``+ bearing_noise z2`` and relative
    heading ``wrap(th_j - th_i + heading_noise z3)`` (the :data:`CAMERA` record ``camera``), written
    into ``rel_xy (N, 2)``, ``rel_heading (N,)`` and ``visible (N,)`` where seen (within ``max_range``
    and ``half_fov``, ``blocked[i]`` False), zeros elsewhere. ``z (3, F)``: the standard normals z1,
    z2, z3 of the F followers, in robot order."""
    cam = camera[0]
    max_range, half_fov = cam.max_range, cam.half_fov
    range_noise, bearing_noise, heading_noise = cam.range_noise, cam.bearing_noise, cam.heading_noise
    n = px.shape[0]
    rel_xy[:] = 0.0
    rel_heading[:] = 0.0
    visible[:] = False
    z1 = z[0]
    z2 = z[1]
    z3 = z[2]
    k = 0
    for i in range(n):
        j = predecessor[i]
        if j < 0:
            continue
        dx = px[j] - px[i]
        dy = py[j] - py[i]
        dist = math.hypot(dx, dy)
        bearing = wrap(math.atan2(dy, dx) - pth[i])
        if dist <= max_range and abs(bearing) <= half_fov and not blocked[i]:
            r = dist * (1.0 + range_noise * z1[k])
            b = bearing + bearing_noise * z2[k]
            rel_xy[i, 0] = r * math.cos(b)
            rel_xy[i, 1] = r * math.sin(b)
            rel_heading[i] = wrap(pth[j] - pth[i] + heading_noise * z3[k])
            visible[i] = True
        k += 1


class OdometryState(NamedTuple):
    """The wheel odometry's per-robot arrays of ``M`` robots
    (:class:`parcover_env.sensors.odometry.Odometry`'s attributes of the same names)."""

    estimate: np.ndarray
    """``(M, 3)`` pose estimates, updated in place."""
    covariance: np.ndarray
    """``(M, 3, 3)`` their covariances, updated in place."""
    travelled: np.ndarray
    """``(M,)`` distance since the last fix, updated in place."""
    turned: np.ndarray
    """``(M,)`` angle turned since the last fix, updated in place."""
    factors: np.ndarray
    """``(M, 2)`` the systematic encoder factors (read)."""
    believed_base: np.ndarray
    """``(M,)`` the wheel base the odometry divides by (read)."""


@njit(cache=True, nogil=True)
def wheel_odometry(state, travel, speed_change, dt, z, errors):
    """One control step of the ``wheels`` odometry
    (:meth:`parcover_env.sensors.odometry.Odometry.measure_wheels`) of ``K`` worlds of ``N`` robots,
    robot by robot (``M = K N`` rows, world ``k``'s robots ``k N ... k N + N - 1``), in place on the
    :class:`OdometryState` ``state``, from each wheel's true distance ``travel (M, 2)`` and summed
    speed changes ``speed_change (M, 2)`` over ``dt`` and the :data:`WHEEL_ERRORS` record ``errors``.
    ``z (K, 4 N)``: world ``k``'s standard normals, flat ``(2, N, 2)``: the slip factors, then the
    random wheel errors."""
    for m in range(state.estimate.shape[0]):
        _wheel_step(m, z, state, travel, speed_change, dt, errors)


@njit(cache=True, nogil=True)
def wheel_odometry_rows(state, travel, speed_change, dt, z, errors, velocity, fix_age):
    """:func:`wheel_odometry` (the same arguments and floats), and per robot: the encoder velocity
    ``velocity (M, 2)`` over the step (the signed distance between the estimates before and after,
    signed by the wheels' true travel, and the wrapped heading change, each over ``dt``), its
    ``fix_age (M,)`` plus ``dt``; the wheel distances and speed changes read are then zeroed (taken
    from the drive, :meth:`~parcover_env.world.drive.DiffDrive.take_travel`)."""
    est = state.estimate
    for m in range(est.shape[0]):
        x0 = est[m, 0]
        y0 = est[m, 1]
        th0 = est[m, 2]
        _wheel_step(m, z, state, travel, speed_change, dt, errors)
        forward = travel[m, 0] + travel[m, 1]
        sign = 1.0 if forward > 0.0 else (-1.0 if forward < 0.0 else 0.0)
        velocity[m, 0] = math.hypot(est[m, 0] - x0, est[m, 1] - y0) * sign / dt
        velocity[m, 1] = wrap(est[m, 2] - th0) / dt
        fix_age[m] += dt
        for w in range(2):
            travel[m, w] = 0.0
            speed_change[m, w] = 0.0


@njit(cache=True, inline="always")
def _wheel_step(m, z, state, travel, speed_change, dt, errors):
    """Robot ``m`` of :func:`wheel_odometry`."""
    est, factors, believed_base = state.estimate, state.factors, state.believed_base
    err = errors[0]
    wheel_base, slip_accel, slip_turn = err.wheel_base, err.slip_accel, err.slip_turn
    wheel_variance, cov_wheel_variance = err.wheel_variance, err.covariance_wheel_variance
    n = z.shape[1] // 4
    k = m // n
    i = m - k * n
    d0 = travel[m, 0]
    d1 = travel[m, 1]
    turn_rate = abs(d1 - d0) / (wheel_base * dt)
    read0 = 0.0
    read1 = 0.0
    for w in range(2):
        d = travel[m, w]
        slip = abs(z[k, 2 * i + w]) * (slip_accel * speed_change[m, w] / dt + slip_turn * turn_rate)
        read = d * factors[m, w] * (1.0 + slip) + math.sqrt(wheel_variance * abs(d)) * z[k, 2 * n + 2 * i + w]
        if w == 0:
            read0 = read
        else:
            read1 = read
    base = believed_base[m]
    ds = 0.5 * (read0 + read1)
    dth = (read1 - read0) / base
    var_l = cov_wheel_variance * abs(read0)
    var_r = cov_wheel_variance * abs(read1)
    q00 = 0.25 * (var_l + var_r)
    q11 = (var_l + var_r) / (base * base)
    q01 = 0.5 * (var_r - var_l) / base
    mid = est[m, 2] + 0.5 * dth
    c = math.cos(mid)
    s = math.sin(mid)
    _propagate(state.covariance[m], -ds * s, ds * c, c, -0.5 * ds * s, s, 0.5 * ds * c, q00, q01, q11)
    est[m, 0] += ds * c
    est[m, 1] += ds * s
    est[m, 2] = wrap(est[m, 2] + dth)
    state.travelled[m] += abs(ds)
    state.turned[m] += abs(dth)


@njit(cache=True, inline="always")
def _propagate(p, a, b, g00, g01, g10, g11, q00, q01, q11):
    """``p := F p F^T + G Q G^T`` for ``F = [[1, 0, a], [0, 1, b], [0, 0, 1]]``,
    ``G = [[g00, g01], [g10, g11], [0, 1]]`` and the symmetric ``Q = [[q00, q01], [q01, q11]]``."""
    fp = np.empty((3, 3))
    for j in range(3):
        fp[0, j] = p[0, j] + a * p[2, j]
        fp[1, j] = p[1, j] + b * p[2, j]
        fp[2, j] = p[2, j]
    g = ((g00, g01), (g10, g11), (0.0, 1.0))
    for i in range(3):
        gq0 = g[i][0] * q00 + g[i][1] * q01
        gq1 = g[i][0] * q01 + g[i][1] * q11
        row = (fp[i, 0] + a * fp[i, 2], fp[i, 1] + b * fp[i, 2], fp[i, 2])
        for j in range(3):
            p[i, j] = row[j] + (gq0 * g[j][0] + gq1 * g[j][1])
