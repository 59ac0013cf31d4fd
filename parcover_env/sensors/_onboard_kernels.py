"""Compiled (numba) loops of the onboard sensors: the sonar ring (its noise, and the whole ring in
one pass), the follower camera and the wheel odometry. Import only through :mod:`parcover_env.sensors.sonar`,
:mod:`parcover_env.sensors.relative` and :mod:`parcover_env.sensors.odometry`.

The callers draw the random numbers (numpy, the episode's generator, whole arrays in the order the
numpy formulas drew them) and hand them in: passing a ``Generator`` to a compiled function costs
about 5 us per call. ``tests/sensors/test_sonar.py``, ``test_relative_camera.py`` and
``test_odometry.py`` keep the numpy references.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from parcover_env.geometry._ray_kernels import near_segments, sonar_corner_echoes, sonar_crosstalk, sonar_echoes


@njit(cache=True, nogil=True)
def ring_noise(ideal, heard, talk_prob, talk, z, bad, junk, range_min, range_max, drop_below, noise_std, noise_rel,
               quantization, garbage_rate, out):
    """``out (N, B) float32`` from the noise-free ``ideal (N, B)``: cross-talk (``talk_prob > 0``:
    a beam reads ``min(ideal, heard)`` with that probability, ``heard (N, B)``), readings below
    ``range_min`` lost (``drop_below``), Gaussian noise ``noise_std + noise_rel * r`` on echoes,
    quantization of echoes, clamping to ``[range_min, range_max]``, garbage readings uniform in that
    range. The draws, flat ``(N * B,)`` arrays or empty where a step is off: ``talk`` uniform
    (cross-talk), ``z`` standard normal (noise), ``bad`` uniform and ``junk`` uniform in the range
    (garbage)."""
    n, b = ideal.shape
    size = n * b
    r = ideal.copy().reshape(size)
    if talk.shape[0]:
        hv = heard.reshape(size)
        for i in range(size):
            if talk[i] < talk_prob:
                r[i] = min(r[i], hv[i])
    echo = np.empty(size, dtype=np.bool_)
    for i in range(size):
        if drop_below and r[i] < range_min:
            r[i] = range_max
        echo[i] = r[i] < range_max
    if z.shape[0]:
        for i in range(size):
            if echo[i]:
                r[i] = r[i] + (noise_std + noise_rel * r[i]) * z[i]
    for i in range(size):
        if quantization > 0.0 and echo[i]:
            r[i] = np.rint(r[i] / quantization) * quantization
        r[i] = min(max(r[i], range_min), range_max)
    if bad.shape[0]:
        for i in range(size):
            if bad[i] < garbage_rate:
                r[i] = junk[i]
    flat = out.reshape(size)
    for i in range(size):
        flat[i] = r[i]


@njit(cache=True, nogil=True)
def ring_readings(px, py, pth, radius2, beams, offsets, segs, seg_len, pts, u1, u2, specular, multipath, all_round,
                  drop_below, par, talk, z, bad, junk, out):
    """The rings of every robot of ``K`` worlds sharing the walls, ``px, py, pth (K, N)``, in one pass:
    what :meth:`parcover_env.sensors.sonar.SonarRing.measure` composes from its parts for each world
    alone. The noise-free echoes (:func:`~parcover_env.geometry._ray_kernels.sonar_echoes`, concave
    corners; the discs are the other robots of the robot's world, of squared radius ``radius2``), the
    cross-talk of the beams whose uniform ``talk`` draw is below its probability (``talk`` empty:
    none), then :func:`ring_noise` into ``out (K * N, B) float32``. The draws are flat, world after
    world, robot after robot, beam after beam. ``par`` = range max, incidence cosine bound, restart
    nudge, near-list slack, half cone, cross-talk probability, range min, noise sigma, relative
    noise, quantization, garbage rate."""
    rmax, cos_min, nudge, slack, half = par[0], par[1], par[2], par[3], par[4]
    k, n = px.shape
    nb = beams.shape[0]
    ox = px.reshape(k * n)
    oy = py.reshape(k * n)
    axes = np.empty((k * n, nb))
    for r in range(k * n):
        for b in range(nb):
            axes[r, b] = pth[r // n, r % n] + beams[b]
    rows = 1 if k == 1 else k * n  # one disc set for all origins of one world, else a set per origin
    cx = np.empty((rows, n))
    cy = np.empty((rows, n))
    for r in range(rows):
        for d in range(n):
            cx[r, d] = px[r // n, d]
            cy[r, d] = py[r // n, d]
    r2 = np.full(n, radius2)
    owner = np.empty(k * n, dtype=np.int64)
    for r in range(k * n):
        owner[r] = r % n
    idx = np.empty((k * n, segs.shape[0]), dtype=np.int64)
    cnt = np.empty(k * n, dtype=np.int64)
    near_segments(ox, oy, segs, rmax + slack, idx, cnt)
    ideal = np.empty((k * n, nb))
    sonar_echoes(ox, oy, axes, offsets, segs, seg_len, idx, cnt, cx, cy, r2, owner, rmax, specular, multipath,
                 cos_min, nudge, True, ideal)
    if specular and pts.shape[0] > 0:
        sonar_corner_echoes(ox, oy, axes, pts, u1, u2, segs, idx, cnt, cx, cy, r2, owner, rmax, half, ideal)
    heard = ideal  # (no echo reads inf here, range max in the parts: ring_noise treats both alike)
    if talk.shape[0]:
        want = np.empty((k, n, nb), dtype=np.bool_)
        for r in range(k * n):
            for b in range(nb):
                want[r // n, r % n, b] = talk[r * nb + b] < par[5]
        near_segments(ox, oy, segs, 2.0 * rmax + slack, idx, cnt)
        heard3 = np.full((k, n, nb), np.inf)
        sonar_crosstalk(px, py, pth, beams, all_round, segs, idx, cnt, half, rmax, want, heard3)
        heard = heard3.reshape(k * n, nb)
    ring_noise(ideal, heard, par[5] if talk.shape[0] else 0.0, talk, z, bad, junk, par[6], rmax, drop_below, par[7],
               par[8], par[9], par[10], out)


@njit(cache=True, inline="always")
def _wrap(a):
    """``a`` wrapped to (-pi, pi], as :func:`parcover_env.geometry.angles.wrap_angle`."""
    return math.pi - ((math.pi - a) % (2.0 * math.pi))


@njit(cache=True, nogil=True)
def camera_view(px, py, pth, predecessor, blocked, z, max_range, half_fov, range_noise, bearing_noise,
                heading_noise, rel_xy, rel_heading, visible):
    """The follower camera (:meth:`parcover_env.sensors.relative.RelativeCamera.measure`) of robots
    ``px, py, pth (N,)``: for each follower ``i`` (``predecessor[i] >= 0``, F of them) of its
    predecessor ``j``: range ``r (1 + range_noise z1)``, bearing ``+ bearing_noise z2`` and relative
    heading ``wrap(th_j - th_i + heading_noise z3)``, written where seen (within ``max_range`` and
    ``half_fov``, ``blocked[i]`` False), zeros elsewhere. ``z (3, F)``: the standard normals z1, z2,
    z3 of the F followers, in robot order."""
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
        bearing = _wrap(math.atan2(dy, dx) - pth[i])
        if dist <= max_range and abs(bearing) <= half_fov and not blocked[i]:
            r = dist * (1.0 + range_noise * z1[k])
            b = bearing + bearing_noise * z2[k]
            rel_xy[i, 0] = r * math.cos(b)
            rel_xy[i, 1] = r * math.sin(b)
            rel_heading[i] = _wrap(pth[j] - pth[i] + heading_noise * z3[k])
            visible[i] = True
        k += 1


@njit(cache=True, nogil=True)
def wheel_odometry(est, cov, travelled, turned, travel, speed_change, dt, z, factors, believed_base, wheel_base,
                   slip_accel, slip_turn, wheel_variance, cov_wheel_variance):
    """One control step of the ``wheels`` odometry
    (:meth:`parcover_env.sensors.odometry.Odometry.measure_wheels`), in place on the estimates
    ``est (N, 3)``, covariances ``cov (N, 3, 3)`` and the ``travelled``/``turned`` sums. ``z``: the
    standard normals, flat ``(2, N, 2)``: the slip factors, then the random wheel errors."""
    n = est.shape[0]
    for i in range(n):
        d0 = travel[i, 0]
        d1 = travel[i, 1]
        turn_rate = abs(d1 - d0) / (wheel_base * dt)
        read0 = 0.0
        read1 = 0.0
        for w in range(2):
            d = travel[i, w]
            slip = abs(z[2 * i + w]) * (slip_accel * speed_change[i, w] / dt + slip_turn * turn_rate)
            read = d * factors[i, w] * (1.0 + slip) + math.sqrt(wheel_variance * abs(d)) * z[2 * n + 2 * i + w]
            if w == 0:
                read0 = read
            else:
                read1 = read
        base = believed_base[i]
        ds = 0.5 * (read0 + read1)
        dth = (read1 - read0) / base
        var_l = cov_wheel_variance * abs(read0)
        var_r = cov_wheel_variance * abs(read1)
        q00 = 0.25 * (var_l + var_r)
        q11 = (var_l + var_r) / (base * base)
        q01 = 0.5 * (var_r - var_l) / base
        mid = est[i, 2] + 0.5 * dth
        c = math.cos(mid)
        s = math.sin(mid)
        _propagate(cov[i], -ds * s, ds * c, c, -0.5 * ds * s, s, 0.5 * ds * c, q00, q01, q11)
        est[i, 0] += ds * c
        est[i, 1] += ds * s
        est[i, 2] = _wrap(est[i, 2] + dth)
        travelled[i] += abs(ds)
        turned[i] += abs(dth)


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
