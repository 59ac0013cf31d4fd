"""Compiled (numba) ``fast`` sonar ring, the training option of :mod:`parcover_env.sensors.sonar`:
one ray per beam along its axis, the robots of the beam's own world as discs, then Gaussian range
noise, dropouts, quantization and garbage readings with the realistic model's parameters
(:func:`~parcover_env.sensors.sonar_ring_kernels.ring_noise`). No cone, no specular incidence
limit, no multipath, no corner echoes, no cross-talk.

The caller draws the random numbers (numpy, each world's own generator, in the order of
:class:`FastDraws`) and hands them in; the kernels read their constants from the
:data:`~parcover_env.sensors.sonar_kernels.SONAR_RULES` record.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from parcover_env.geometry.ray_kernels import BOX_SLACK, disc_fan, segment_fan
from parcover_env.geometry.wall_grid import near_segments_grid
from parcover_env.sensors.sonar_ring_kernels import Draws, ring_noise

__all__ = ["FastDraws", "fast_noise", "fast_ring_readings", "segment_fan", "disc_fan"]


class FastDraws(NamedTuple):
    """The random numbers of a ``fast`` ring's readings, flat ``(R,)`` arrays (world after world,
    robot after robot, beam after beam), drawn in this order, empty where that step is off."""

    z: np.ndarray
    """Standard normals: the range noise."""
    drop: np.ndarray
    """Uniforms: an echo is lost (reads ``range_max``) where below ``dropout_prob``."""
    bad: np.ndarray
    """Uniforms: a garbage reading where below its rate."""
    junk: np.ndarray
    """Uniforms in ``[range_min, range_max]``: the garbage readings."""


@njit(cache=True, nogil=True)
def fast_noise(ideal, draws, rules, out):
    """``out (N, B)`` from the noise-free ``ideal (N, B)`` (inf or ``>= range_max``: no echo): echoes
    whose ``draws.drop`` uniform is below ``dropout_prob`` are lost, then
    :func:`~parcover_env.sensors.sonar_ring_kernels.ring_noise` without cross-talk (drops below
    ``range_min``, noise, quantization, clamping, garbage)."""
    rule = rules[0]
    n, b = ideal.shape
    r = ideal.copy()
    drop = draws.drop
    if drop.shape[0]:
        flat = r.reshape(n * b)
        for i in range(n * b):
            if drop[i] < rule.dropout_prob:
                flat[i] = np.inf
    ring_noise(r, r, 0.0, Draws(drop[:0], draws.z, draws.bad, draws.junk), rules, out)


@njit(cache=True, nogil=True)
def fast_ring_readings(poses, radius2, beams, segs, grid, draws, rules, out):
    """Readings ``out (K * N, B) float32`` of the ``fast`` rings (beam axes ``beams (B,)`` in the
    robot frame) of every robot of ``K`` worlds sharing the walls ``segs (S, 4)``, poses ``(K, N, 3)``
    (C-contiguous): per beam, the nearest hit within ``range_max`` of one ray along its axis on the
    walls (those within ``range_max`` of the robot, :func:`near_segments_grid` with the walls'
    :class:`~parcover_env.geometry.wall_grid.WallGrid` ``grid``; :func:`segment_fan`) and on the
    other robots of its world (discs of squared radius ``radius2``; those within ``range_max`` of the
    robot, their terms computed once for all its beams, :func:`disc_fan`), inf if none (a hit beyond
    ``range_max`` is no echo either); then :func:`fast_noise` with the :class:`FastDraws`. Row
    ``k * N + i`` equals what world ``k`` alone reads."""
    rule = rules[0]
    rmax = rule.range_max
    cull = rule.box_cull and math.isfinite(rmax)
    px = np.ascontiguousarray(poses[:, :, 0])
    py = np.ascontiguousarray(poses[:, :, 1])
    pth = np.ascontiguousarray(poses[:, :, 2])
    k, n = px.shape
    nb = beams.shape[0]
    ox = px.reshape(k * n)
    oy = py.reshape(k * n)
    idx = np.empty((k * n, segs.shape[0]), dtype=np.int64)
    cnt = np.empty(k * n, dtype=np.int64)
    near_segments_grid(ox, oy, segs, rmax + rule.near_slack, grid, idx, cnt)
    # a disc farther than range_max + its radius (c above ``reach_c``) cannot be hit within range_max
    reach_c = ((rmax + math.sqrt(radius2)) ** 2 - radius2) * (1.0 + 1e-9) + 1e-9
    bx = np.empty(n)
    by = np.empty(n)
    bc = np.empty(n)
    dx = np.empty(nb)
    dy = np.empty(nb)
    boxes = np.empty((4 if cull else 0, nb))
    walls = np.empty(nb)
    wall_i = np.empty(nb, dtype=np.int64)
    wall_den = np.empty(nb)
    discs = np.empty(nb)
    ideal = np.empty((k * n, nb))
    for w in range(k):
        for i in range(n):
            o = w * n + i
            x0 = ox[o]
            y0 = oy[o]
            m = 0  # the discs of the other robots of world w in reach, in robot order (disc_hit's terms)
            for d in range(n):
                if d == i:
                    continue
                ocx = x0 - px[w, d]
                ocy = y0 - py[w, d]
                c = (ocx * ocx + ocy * ocy) - radius2
                if c <= reach_c:
                    bx[m] = ocx
                    by[m] = ocy
                    bc[m] = c
                    m += 1
            for b in range(nb):
                a = pth[w, i] + beams[b]
                dx[b] = math.cos(a)
                dy[b] = math.sin(a)
                discs[b] = np.inf
                if cull:  # the box of segment_hit's culling
                    fx = x0 + dx[b] * rmax
                    fy = y0 + dy[b] * rmax
                    boxes[0, b] = min(x0, fx) - BOX_SLACK
                    boxes[1, b] = max(x0, fx) + BOX_SLACK
                    boxes[2, b] = min(y0, fy) - BOX_SLACK
                    boxes[3, b] = max(y0, fy) + BOX_SLACK
            segment_fan(x0, y0, dx, dy, segs, idx[o, :cnt[o]], boxes, walls, wall_i, wall_den)
            disc_fan(dx, dy, bx[:m], by[:m], bc[:m], discs)
            for b in range(nb):  # a hit beyond range_max is no echo, like none (inf)
                ideal[o, b] = min(walls[b], discs[b])
    fast_noise(ideal, draws, rules, out)
