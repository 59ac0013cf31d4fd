"""Compiled (numba) per-pixel loops of the Kinect's frames mode; import only through
:mod:`parcover_env.sensors.kinect`, which draws every random number itself (numpy, same stream)
and hands the draws in. Every pixel goes through the float32 operations, in the order, of the
formulas in :meth:`~parcover_env.sensors.kinect.KinectSensor.noisy_depth` (numpy's float32
arithmetic, with Python constants rounded to float32 first), so the images are unchanged bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_F32_SIGMA0 = np.float32(0.0012)
_F32_SIGMA2 = np.float32(0.0019)
_F32_Z0 = np.float32(0.4)
_F32_EIGHT = np.float32(8.0)
_F32_ZERO = np.float32(0.0)


@njit(cache=True, nogil=True, error_model="numpy")
def depth_noise(depth, normal, fb, z_min, z_max, out):
    """``out (H, W) float32``: ``depth (H, W)`` (inf = no surface) with axial noise
    ``(0.0012 + 0.0019 (z - 0.4)^2) * normal``, 1/8-px disparity quantization ``fb / (rint(8 fb / z) / 8)``
    and the range ``[z_min, z_max]`` (0 outside, or where there was no surface). All float32."""
    h, w = depth.shape
    for i in range(h):
        for j in range(w):
            z = np.float32(depth[i, j])
            if not math.isfinite(z):
                out[i, j] = _F32_ZERO
                continue
            dz = z - _F32_Z0
            z = z + (_F32_SIGMA0 + _F32_SIGMA2 * (dz * dz)) * normal[i, j]
            disp = np.rint(fb / z * _F32_EIGHT) / _F32_EIGHT
            z = fb / disp
            out[i, j] = z if (math.isfinite(z) and z >= z_min and z <= z_max) else _F32_ZERO


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
