"""Compiled (numba) noise of the sonar ring; import only through :mod:`parcover_env.sensors.sonar`.

The kernel draws from the episode's ``numpy.random.Generator`` itself: numba's generator methods
advance the same state and return the same numbers as numpy's, so drawing whole arrays here, in
the order the numpy formulas of :meth:`~parcover_env.sensors.sonar.SonarRing.measure` draw them,
gives the same readings bit for bit (``tests/sensors/test_sonar.py`` keeps the numpy reference).
"""

from __future__ import annotations

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
