"""Angles and planar rotations: the package's one angle-wrapping convention, (-pi, pi]."""

from __future__ import annotations

import math

import numpy as np

from parcover_env.geometry.wrap_formula import wrap

__all__ = ["wrap", "wrap_angle", "rotate", "atan2"]


def wrap_angle(a):
    """Angles (rad, scalar or array) wrapped to (-pi, pi]: :func:`wrap` element-wise (a compiled ufunc)."""
    return _kernels().wrap_angles(np.asarray(a, dtype=float))


def rotate(v: np.ndarray, theta) -> np.ndarray:
    """Rotate vectors ``v (..., 2)`` by ``theta`` (broadcast)."""
    c, s = np.cos(theta), np.sin(theta)
    x, y = v[..., 0], v[..., 1]
    return np.stack([c * x - s * y, s * x + c * y], axis=-1)


def atan2(y, x):
    """``arctan2(y, x)`` (rad, broadcast) with the same bits on every CPU.

    numpy's ``arctan2`` takes a SIMD path on CPUs with AVX-512 whose last bits differ from libm's,
    which it uses on other CPUs; a rollout must not depend on the CPU it ran on, so scalars go to
    ``math.atan2`` and arrays to a compiled loop over it (libm either way)."""
    if np.ndim(y) == 0 and np.ndim(x) == 0:
        return np.float64(math.atan2(float(y), float(x)))
    yy, xx = np.broadcast_arrays(np.asarray(y, dtype=float), np.asarray(x, dtype=float))
    out = np.empty(yy.shape)
    _kernels().atan2_into(np.ascontiguousarray(yy).reshape(-1), np.ascontiguousarray(xx).reshape(-1),
                            out.reshape(-1))
    return out


_LOADED: dict = {}


def _kernels():
    """:mod:`parcover_env.geometry.angle_kernels` (numba is imported on first use, not with the package;
    kept after that, so a call costs a dict lookup, not an import statement)."""
    kernels = _LOADED.get("k")
    if kernels is None:
        from parcover_env.geometry import angle_kernels as kernels

        _LOADED["k"] = kernels
    return kernels
