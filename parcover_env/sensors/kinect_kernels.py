"""Compiled (numba) per-pixel loops of the Kinect's frames mode, the internals of
:mod:`parcover_env.sensors.kinect` (public so that tests and other rooms may use them), which draws
every random number itself (numpy, the episode's generator) and hands the draws in. The depth noise
is float32 arithmetic (Python constants rounded to float32 first); the robot drawing repeats, in
float64 and in the same order, the cylinder and marker-disc formulas of the numpy reference in
``tests/references/kinect.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["MARKER_DISCS", "depth_noise", "lateral_shift", "draw_robots", "marker_codes", "ir_levels"]

MARKER_DISCS = np.dtype([
    ("marker_r2", "f8"),  # squared radius of a marker disc (m^2): saturates the IR image
    ("halo_r2", "f8"),  # squared radius around a marker centre where depth is missing (m^2)
])
"""The marker discs of :func:`marker_codes` (a record, :mod:`parcover_env.geometry.records`)."""

_F32_SIGMA0 = np.float32(0.0012)
_F32_SIGMA2 = np.float32(0.0019)
_F32_Z0 = np.float32(0.4)
_F32_EIGHT = np.float32(8.0)
_F32_ZERO = np.float32(0.0)


@njit(cache=True, nogil=True, error_model="numpy")
def depth_noise(depth, draws, normal, shift, fb, z_min, z_max, out):
    """``out (H, W) float32``: ``depth (H, W)`` (inf = no surface) with axial noise
    ``(0.0012 + 0.0019 (z - 0.4)^2) * normal[draws >> shift]`` (``normal``: float32 standard-normal
    values indexed by the top bits of the integer ``draws (H, W)``), 1/8-px disparity quantization
    ``fb / (rint(8 fb / z) / 8)`` and the range ``[z_min, z_max]`` (0 outside, or where there was
    no surface). All float32."""
    h, w = depth.shape
    fb8 = fb * _F32_EIGHT  # fb / (rint(8 fb / z) / 8) == 8 fb / rint(8 fb / z): scaling by 8 is exact
    inf = np.float32(np.inf)
    for i in range(h):
        for j in range(w):  # no branch but the final select: the loop stays cheap
            z = np.float32(depth[i, j])
            dz = z - _F32_Z0
            zq = fb8 / np.rint(fb8 / (z + (_F32_SIGMA0 + _F32_SIGMA2 * (dz * dz)) * normal[draws[i, j] >> shift]))
            ok = (z < inf) & (zq >= z_min) & (zq <= z_max)  # also False for NaN
            out[i, j] = zq if ok else _F32_ZERO


@njit(cache=True, nogil=True)
def lateral_shift(depth, draws, table, out):
    """``out[v, u] = depth[v + table[draws[0, v, u]], u + table[draws[1, v, u]]]``, the displaced
    pixel clamped to the image."""
    h, w = depth.shape
    for i in range(h):
        for j in range(w):
            r = min(max(i + table[draws[0, i, j]], 0), h - 1)
            c = min(max(j + table[draws[1, i, j]], 0), w - 1)
            out[i, j] = depth[r, c]


@njit(cache=True, nogil=True, error_model="numpy")
def draw_robots(depth, owner, top, rays, C, boxes, xy, r2, height):
    """Draw the robot cylinders (radius ``sqrt(r2)``, top disc at ``height``) in robot order into
    ``depth (H, W)`` (ray parameter, kept where nearer), ``owner (H, W)`` (robot index) and ``top``
    (the pixel sees the robot's top disc), over each robot's pixel box ``boxes (N, 4)``
    (u0, v0, u1, v1; ``u0 < 0`` = not drawn); ``rays (H, W, 3)`` from the camera centre ``C (3,)``."""
    inf = np.inf
    for i in range(len(boxes)):
        u0, v0, u1, v1 = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
        if u0 < 0:
            continue
        x, y = xy[i, 0], xy[i, 1]
        ox, oy = C[0] - x, C[1] - y
        c_side = ox * ox + oy * oy - r2
        for v in range(v0, v1):
            for u in range(u0, u1):
                d0, d1, d2 = rays[v, u, 0], rays[v, u, 1], rays[v, u, 2]
                t_top = (height - C[2]) / d2
                px = C[0] + d0 * t_top - x
                py = C[1] + d1 * t_top - y
                on_top = t_top > 0 and px * px + py * py <= r2
                a = d0 * d0 + d1 * d1
                b = ox * d0 + oy * d1
                disc = b * b - a * c_side
                t = t_top if on_top else inf
                if disc > 0:
                    t_side = (-b - math.sqrt(disc)) / a
                    z_side = C[2] + t_side * d2
                    if t_side > 0 and z_side >= 0 and z_side <= height and t_side < t:
                        t = t_side
                if t < depth[v, u]:
                    depth[v, u] = t
                    owner[v, u] = i
                    top[v, u] = on_top and t_top <= t


@njit(cache=True, nogil=True, error_model="numpy")
def marker_codes(code, depth, owner, top, rays, C, boxes, poses, cos_sin, carriers, pattern, discs):
    """Marker code of every pixel showing a carrier's top disc (as :func:`draw_robots` left
    ``depth``, ``owner`` and ``top``): 1 within ``sqrt(marker_r2)`` of a marker centre (``pattern
    (K, 2)``, robot frame), 2 within ``sqrt(halo_r2)`` (depth-missing halo), else 0 (the
    :data:`MARKER_DISCS` record ``discs``). ``carriers``: robot indices; ``cos_sin (N, 2)``: cos and
    sin of each robot's heading."""
    rm2, rh2 = discs[0].marker_r2, discs[0].halo_r2
    for i in carriers:
        u0, v0, u1, v1 = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
        if u0 < 0:
            continue
        x, y = poses[i, 0], poses[i, 1]
        c, s = cos_sin[i, 0], cos_sin[i, 1]
        for v in range(v0, v1):
            for u in range(u0, u1):
                if owner[v, u] != i or not top[v, u]:
                    continue
                t = depth[v, u]
                p0 = C[0] + rays[v, u, 0] * t - x
                p1 = C[1] + rays[v, u, 1] * t - y
                q0 = c * p0 + s * p1
                q1 = -s * p0 + c * p1
                d2 = np.inf
                for k in range(len(pattern)):
                    e0, e1 = q0 - pattern[k, 0], q1 - pattern[k, 1]
                    d2 = min(d2, e0 * e0 + e1 * e1)
                code[v, u] = 1 if d2 <= rm2 else (2 if d2 <= rh2 else 0)


@njit(cache=True, nogil=True)
def ir_levels(static_ir, owner, noise, robot_level, out):
    """``out (H, W) uint8``: the dull IR level of each pixel (``robot_level`` where a robot is seen,
    ``owner >= 0``, else the static scene's) plus ``noise >> 3`` (uniform 0-31 from uniform bytes;
    the levels are small: no overflow)."""
    h, w = out.shape
    for i in range(h):
        for j in range(w):
            out[i, j] = (robot_level if owner[i, j] >= 0 else static_ir[i, j]) + (noise[i, j] >> 3)
