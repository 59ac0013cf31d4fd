"""Compiled (numba) ring of the sonar, the internals of :mod:`parcover_env.sensors.sonar` (public so
that tests and other rooms may use them): cross-talk between robots, the noise of the readings,
and the whole ring of every robot of K worlds in one call (:func:`ring_readings`), built on the
echoes of :mod:`parcover_env.sensors.sonar_kernels` and reading the same
:data:`~parcover_env.sensors.sonar_kernels.SONAR_RULES` record.

The caller draws the random numbers (numpy, the episode's generator, whole arrays in the order the
numpy formulas drew them) and hands them in as :class:`Draws`: passing a ``Generator`` to a
compiled function costs about 5 us per call. ``tests/references/sonar.py`` keeps the plain-Python
references.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.geometry.ray_kernels import in_cone, segment_hit
from parcover_env.geometry.wall_grid import near_segments_grid
from parcover_env.sensors.sonar_kernels import Discs, sonar_corner_echoes, sonar_echoes

__all__ = ["Draws", "sonar_crosstalk", "ring_noise", "ring_readings"]


class Draws(NamedTuple):
    """The random numbers of a ring's readings, flat ``(R,)`` arrays (world after world, robot after
    robot, beam after beam), empty where that step is off."""

    talk: np.ndarray
    """Uniforms: cross-talk where below its probability."""
    z: np.ndarray
    """Standard normals: the noise."""
    bad: np.ndarray
    """Uniforms: a garbage reading where below its rate."""
    junk: np.ndarray
    """Uniforms in ``[range_min, range_max]``: the garbage readings."""


_CONE_SLACK = 1e-6
"""Margin (rad) of the cross-talk's cone pre-test (:func:`sonar_crosstalk`): a robot more than this
outside every wanted cone skips the exact bearing test, which rounding never makes pass."""


@njit(cache=True, nogil=True)
def sonar_crosstalk(px, py, pth, beams, all_round, segs, rules, want, out):
    """Cross-talk readings ``out (K, N, B)`` (left inf where none) of robots ``(K, N)`` poses
    ``px, py, pth``: beam ``b`` of robot ``i`` reads ``d / 2`` from the nearest robot ``j`` of its world
    inside that beam's cone (``half_cone``) with a beam of ``j`` pointing back at ``i``, ``0 < d / 2 <= range_max``
    and no wall between them; the rules of :func:`parcover_env.sensors.sonar.crosstalk`.
    ``all_round``: the cones cover every direction (a beam always points back). The wall test of a
    pair box-culls the walls (few pairs come to it: a near-wall list per robot would cost more).
    Only the beams ``want (K, N, B)`` are computed (the others stay inf). A robot ``j`` beyond ``2
    range_max`` (squared distances, with a relative slack of 1e-9) or more than ``_CONE_SLACK``
    outside every wanted cone of ``i`` (squared dot products with the axes, when the cones are
    narrower than a half turn) skips the exact tests, which rounding never makes pass."""
    half, rmax = rules[0].half_cone, rules[0].range_max
    nb = beams.shape[0]
    n_robots = px.shape[1]
    cos_lim = math.cos(min(half + _CONE_SLACK, math.pi))
    cos2 = cos_lim * cos_lim * (1.0 - 1e-9)  # the pre-test: dot >= 0 and dot^2 >= cos2 d^2 (if cos_lim > 0)
    reach2 = 4.0 * rmax * rmax * (1.0 + 1e-9)
    wb = np.empty(nb, dtype=np.int64)  # per robot: its wanted beams and their unit axes
    wx = np.empty(nb)
    wy = np.empty(nb)
    every = np.arange(segs.shape[0])
    for k in range(px.shape[0]):
        for i in range(n_robots):
            nw = 0
            for b in range(nb):
                if want[k, i, b]:
                    wb[nw] = b
                    wx[nw] = math.cos(pth[k, i] + beams[b])
                    wy[nw] = math.sin(pth[k, i] + beams[b])
                    nw += 1
            if nw == 0:
                continue
            for j in range(n_robots):
                if i == j:
                    continue
                dx = px[k, j] - px[k, i]
                dy = py[k, j] - py[k, i]
                d2 = dx * dx + dy * dy
                if not d2 <= reach2:
                    continue
                near_axis = cos_lim <= 0.0  # a wanted beam whose axis is within the cone (plus a slack) of j
                for q in range(0 if near_axis else nw):
                    dot = dx * wx[q] + dy * wy[q]
                    if dot >= 0.0 and dot * dot >= cos2 * d2:
                        near_axis = True
                        break
                if not near_axis:
                    continue
                d = math.hypot(dx, dy)
                if not (d / 2 <= rmax and d > 0):
                    continue
                bearing = math.atan2(dy, dx)
                gain = False  # does a beam of i hold j nearer than what it heard so far?
                for b in range(nb):
                    if want[k, i, b] and d / 2 < out[k, i, b] and in_cone(bearing - pth[k, i] - beams[b], half):
                        gain = True
                        break
                if not gain:
                    continue
                back = all_round
                for c in range(0 if all_round else nb):
                    if in_cone(bearing + math.pi - pth[k, j] - beams[c], half):
                        back = True
                        break
                if not back:
                    continue
                _, hit, _ = segment_hit(px[k, i], py[k, i], dx, dy, segs, every, 1.0, True, True)
                if hit >= 0:
                    continue  # a wall between them
                for b in range(nb):
                    if want[k, i, b] and d / 2 < out[k, i, b] and in_cone(bearing - pth[k, i] - beams[b], half):
                        out[k, i, b] = d / 2



@njit(cache=True, nogil=True)
def ring_noise(ideal, heard, talk_prob, draws, rules, out):
    """``out (N, B)`` (float32 or float64) from the noise-free ``ideal (N, B)``: cross-talk
    (``talk_prob > 0``: a beam reads ``min(ideal, heard)`` with that probability, ``heard (N, B)``),
    then the :data:`SONAR_RULES`: readings below ``range_min`` lost (``drop_below``), Gaussian noise
    ``noise_std + noise_rel * r`` on echoes, quantization of echoes, clamping to ``[range_min,
    range_max]``, garbage readings uniform in that range. The :class:`Draws` are ``(N * B,)``."""
    talk, z, bad, junk = draws
    rule = rules[0]
    range_min, range_max, drop_below = rule.range_min, rule.range_max, rule.drop_below
    noise_std, noise_rel, quantization, garbage_rate = rule.noise_std, rule.noise_rel, rule.quantization, \
        rule.garbage_rate
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
def ring_readings(poses, radius2, beams, offsets, share, walls, grid, draws, rules, out):
    """The rings (beam axes ``beams (B,)`` in the robot frame, sub-rays ``offsets`` shared as
    ``share`` says) of every robot of ``K`` worlds sharing the :class:`WallSet` (its near-wall lists
    from the :class:`~parcover_env.geometry.wall_grid.WallGrid` ``grid``), ``poses (K, N, 3)``
    (C-contiguous), in one pass: what :meth:`parcover_env.sensors.sonar.SonarRing.measure` composes from its
    parts for each world alone. The noise-free echoes (:func:`sonar_echoes`, its concave corners;
    the discs are the other robots of the robot's world, of squared radius ``radius2``), the
    cross-talk of the beams whose uniform ``draws.talk`` is below its probability (``talk`` empty:
    none), then :func:`ring_noise` into ``out (K * N, B) float32``, with the :data:`SONAR_RULES`
    ``rules``. The :class:`Draws` are flat, world after world, robot after robot, beam after beam."""
    rule = rules[0]
    rmax, slack = rule.range_max, rule.near_slack
    segs = walls.segments
    talk = draws.talk
    px = np.ascontiguousarray(poses[:, :, 0])
    py = np.ascontiguousarray(poses[:, :, 1])
    pth = np.ascontiguousarray(poses[:, :, 2])
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
    discs = Discs(cx, cy, r2, owner)
    idx = np.empty((k * n, segs.shape[0]), dtype=np.int64)
    cnt = np.empty(k * n, dtype=np.int64)
    near_segments_grid(ox, oy, segs, rmax + slack, grid, idx, cnt)
    ideal = np.empty((k * n, nb))
    sonar_echoes(ox, oy, axes, offsets, share, walls, idx, cnt, discs, rules, ideal)
    if rule.specular and walls.points.shape[0] > 0:
        sonar_corner_echoes(ox, oy, axes, walls, idx, cnt, discs, rules, ideal)
    heard = ideal  # (no echo reads inf here, range max in the parts: ring_noise treats both alike)
    if talk.shape[0]:
        want = np.empty((k, n, nb), dtype=np.bool_)
        for r in range(k * n):
            for b in range(nb):
                want[r // n, r % n, b] = talk[r * nb + b] < rule.crosstalk_prob
        heard3 = np.full((k, n, nb), np.inf)
        sonar_crosstalk(px, py, pth, beams, rule.all_round, segs, rules, want, heard3)
        heard = heard3.reshape(k * n, nb)
    ring_noise(ideal, heard, rule.crosstalk_prob if talk.shape[0] else 0.0, draws, rules, out)
