"""Compiled (numba) loops of the onboard sensors: the sonar ring's noise and the follower camera.
Import only through :mod:`parcover_env.sensors.sonar` and :mod:`parcover_env.sensors.relative`.

The kernels draw from the episode's ``numpy.random.Generator`` itself: numba's generator methods
advance the same state and return the same numbers as numpy's, so drawing whole arrays here, in
the order the numpy formulas of the sensors drew them, gives the same readings bit for bit
(``tests/sensors/test_sonar.py`` and ``tests/sensors/test_relative.py`` keep the numpy references).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def ring_noise(ideal, heard, talk_prob, rng, noisy, range_min, range_max, drop_below, noise_std, noise_rel,
               quantization, garbage_rate, out):
    """``out (N, B) float32`` from the noise-free ``ideal (N, B)``: cross-talk (``talk_prob > 0``:
    a beam reads ``min(ideal, heard)`` with that probability, ``heard (N, B)``), readings below
    ``range_min`` lost (``drop_below``), Gaussian noise ``noise_std + noise_rel * r`` on echoes,
    quantization of echoes, clamping to ``[range_min, range_max]``, garbage readings uniform in that
    range. Random draws only if ``noisy``; each is one ``(N, B)`` array, in that order."""
    n, b = ideal.shape
    size = n * b
    r = ideal.copy().reshape(size)
    if noisy and talk_prob > 0.0:
        talk = rng.random(size)
        hv = heard.reshape(size)
        for i in range(size):
            if talk[i] < talk_prob:
                r[i] = min(r[i], hv[i])
    echo = np.empty(size, dtype=np.bool_)
    for i in range(size):
        if drop_below and r[i] < range_min:
            r[i] = range_max
        echo[i] = r[i] < range_max
    if noisy and (noise_std > 0.0 or noise_rel > 0.0):
        z = rng.standard_normal(size)
        for i in range(size):
            if echo[i]:
                r[i] = r[i] + (noise_std + noise_rel * r[i]) * z[i]
    for i in range(size):
        if quantization > 0.0 and echo[i]:
            r[i] = np.rint(r[i] / quantization) * quantization
        r[i] = min(max(r[i], range_min), range_max)
    if noisy and garbage_rate > 0.0:
        bad = rng.random(size)
        junk = rng.uniform(range_min, range_max, size)
        for i in range(size):
            if bad[i] < garbage_rate:
                r[i] = junk[i]
    flat = out.reshape(size)
    for i in range(size):
        flat[i] = r[i]


@njit(cache=True, inline="always")
def _wrap(a):
    """``a`` wrapped to (-pi, pi], as :func:`parcover_env.geometry.angles.wrap_angle`."""
    return math.pi - ((math.pi - a) % (2.0 * math.pi))


@njit(cache=True, nogil=True)
def camera_view(px, py, pth, predecessor, blocked, rng, max_range, half_fov, range_noise, bearing_noise,
                heading_noise, rel_xy, rel_heading, visible):
    """The follower camera (:meth:`parcover_env.sensors.relative.RelativeCamera.measure`) of robots
    ``px, py, pth (N,)``: for each follower ``i`` (``predecessor[i] >= 0``, F of them) of its
    predecessor ``j``: range ``r (1 + range_noise z1)``, bearing ``+ bearing_noise z2`` and relative
    heading ``wrap(th_j - th_i + heading_noise z3)``, written where seen (within ``max_range`` and
    ``half_fov``, ``blocked[i]`` False), zeros elsewhere. Draws three (F,) standard normals, z1 then
    z2 then z3."""
    n = px.shape[0]
    f = 0
    for i in range(n):
        if predecessor[i] >= 0:
            f += 1
    rel_xy[:] = 0.0
    rel_heading[:] = 0.0
    visible[:] = False
    if f == 0:
        return
    z1 = rng.standard_normal(f)
    z2 = rng.standard_normal(f)
    z3 = rng.standard_normal(f)
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
