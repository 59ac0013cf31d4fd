"""Compiled (numba) loops over libm functions; import only through :mod:`parcover_env.geometry.angles`."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True)
def atan2_into(y, x, out):
    """``out[i] = atan2(y[i], x[i])`` (libm) over flat arrays."""
    for i in range(out.shape[0]):
        out[i] = math.atan2(y[i], x[i])
