"""Compiled (numba) angle functions, public so the compiled loops of every room use the same ones:
:func:`wrap`, the one angle wrap (:func:`parcover_env.geometry.wrap_formula.wrap` compiled for kernels),
:data:`wrap_angles`, the same function as a numpy ufunc (behind
:func:`~parcover_env.geometry.angles.wrap_angle`), and libm's ``atan2`` over arrays (behind
:func:`~parcover_env.geometry.angles.atan2`). Importing this module imports numba: the Python side
(:mod:`parcover_env.geometry.angles`) imports it on first use.
"""

from __future__ import annotations

import math

from numba import njit, vectorize

from parcover_env.geometry.wrap_formula import wrap as _formula

__all__ = ["wrap", "wrap_angles", "atan2_into"]

wrap = njit(cache=True, inline="always")(_formula)
"""``a`` wrapped to (-pi, pi] inside compiled code: :func:`parcover_env.geometry.wrap_formula.wrap`, the same
float operations (no fast-math)."""



@vectorize(["float64(float64)"], cache=True)
def _wrap_each(a):
    return wrap(a)


wrap_angles = _wrap_each.ufunc
""":func:`wrap` element-wise: a numpy ufunc over float64 (the plain ufunc, without numba's dispatch
in front: it is called at every step)."""


@njit(cache=True, nogil=True)
def atan2_into(y, x, out):
    """``out[i] = atan2(y[i], x[i])`` (libm) over flat arrays."""
    for i in range(out.shape[0]):
        out[i] = math.atan2(y[i], x[i])
