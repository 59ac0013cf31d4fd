"""Noise tables of the synthetic Kinect v1 (:mod:`parcover_env.sensors.kinect`): the axial depth
noise of Nguyen, Izadi & Lovell (2012) and the inverse-CDF tables through which the sensor turns
uniform integer draws into normal (axial) and rounded-normal (lateral) noise.
"""

from __future__ import annotations

import functools
import math

import numpy as np

__all__ = ["axial_sigma", "normal_table", "rounded_normal_table"]


def axial_sigma(z) -> np.ndarray:
    """Axial depth noise std (m) at camera depth ``z`` (m), Nguyen, Izadi, Lovell 2012."""
    z = np.asarray(z, dtype=float)
    return 0.0012 + 0.0019 * (z - 0.4) ** 2


@functools.cache
def normal_table(bits: int = 12) -> np.ndarray:
    """Inverse-CDF table of the standard normal, float32, read-only: entry ``u`` of ``2**bits`` is
    the value drawn by the uniform integer ``u``, the quantile at the middle of its probability bin
    (``ndtri((u + 0.5) / 2**bits)``). Symmetric, zero mean; variance 0.9997 for 12 bits."""
    from scipy.special import ndtri

    table = ndtri((np.arange(1 << bits) + 0.5) / (1 << bits)).astype(np.float32)
    table.setflags(write=False)
    return table


def rounded_normal_table(sigma: float, bits: int = 16) -> np.ndarray:
    """Inverse-CDF table of ``round(sigma * Z)``, ``Z ~ N(0, 1)``: entry ``u`` of ``2**bits`` is the
    offset drawn by the uniform integer ``u`` (each offset's probability is exact to ``2**-bits``)."""
    if not sigma > 0:
        raise ValueError(f"sigma must be > 0, got {sigma}")
    from scipy.special import ndtr

    k = np.arange(-(math.ceil(8 * sigma) + 1), math.ceil(8 * sigma) + 2)
    cdf = ndtr((k + 0.5) / sigma)  # P(round(sigma Z) <= k)
    u = (np.arange(1 << bits) + 0.5) / (1 << bits)
    return k[np.minimum(np.searchsorted(cdf, u), len(k) - 1)].astype(np.int32)
