"""Compiled (numba) helpers that do float operations in numpy's order, so that compiled code gives the
bits numpy gives (used by the sonar localizer's kernels, issue 40):

* :func:`mean_of` sums like numpy's ``add.reduce`` over a contiguous row (pairwise: eight
  accumulators per block of up to 128 values, halves above that), after numpy's 0.0 identity;
* :func:`argsort4_table` is numpy's ``argsort`` of every pattern of four values, ties included.
"""

from __future__ import annotations

import itertools

import numpy as np
from numba import njit

__all__ = ["MAX_SUM", "argsort4_table", "block_sum", "mean_of"]


def argsort4_table() -> np.ndarray:
    """``(256, 4)`` int64: numpy's ``argsort`` of every four values with order pattern ``t`` (each value
    coded 0-3 by rank, row ``sum(t[k] * 4**k)``): how numpy orders ties on this machine."""
    table = np.zeros((256, 4), dtype=np.int64)
    for t in itertools.product(range(4), repeat=4):
        table[sum(v * 4**k for k, v in enumerate(t))] = np.argsort(np.array(t, dtype=float))
    return table


@njit(cache=True, nogil=True)
def block_sum(x, lo, n):
    """numpy's pairwise sum of ``x[lo:lo + n]``, ``n <= 128`` (one block)."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += x[i]
        return res
    r0, r1, r2, r3 = x[lo], x[lo + 1], x[lo + 2], x[lo + 3]
    r4, r5, r6, r7 = x[lo + 4], x[lo + 5], x[lo + 6], x[lo + 7]
    i = 8
    stop = n - n % 8
    while i < stop:
        r0 += x[lo + i]
        r1 += x[lo + i + 1]
        r2 += x[lo + i + 2]
        r3 += x[lo + i + 3]
        r4 += x[lo + i + 4]
        r5 += x[lo + i + 5]
        r6 += x[lo + i + 6]
        r7 += x[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += x[lo + i]
        i += 1
    return res


@njit(cache=True, nogil=True)
def _halves1(x, lo, n):
    """numpy's pairwise sum of ``x[lo:lo + n]``, ``n <= 256``: halves (the first a multiple of 8) above 128."""
    if n <= 128:
        return block_sum(x, lo, n)
    n2 = n // 2
    n2 -= n2 % 8
    return block_sum(x, lo, n2) + block_sum(x, lo + n2, n - n2)


@njit(cache=True, nogil=True)
def _halves2(x, lo, n):
    """The same, ``n <= 512``."""
    if n <= 128:
        return block_sum(x, lo, n)
    n2 = n // 2
    n2 -= n2 % 8
    return _halves1(x, lo, n2) + _halves1(x, lo + n2, n - n2)


@njit(cache=True, nogil=True)
def _pairwise(x, lo, n):
    """The same, ``n <= MAX_SUM`` (numba compiles no recursion: three levels of halving)."""
    if n <= 128:
        return block_sum(x, lo, n)
    n2 = n // 2
    n2 -= n2 % 8
    return _halves2(x, lo, n2) + _halves2(x, lo + n2, n - n2)


MAX_SUM = 1024
"""Longest row :func:`mean_of` sums like numpy (a scan of up to 1024 readings)."""


@njit(cache=True, nogil=True)
def mean_of(x, n):
    """Mean of ``x[:n]`` as numpy's ``mean`` of a contiguous row (pairwise sum), ``n <= MAX_SUM``."""
    return (0.0 + _pairwise(x, 0, n)) / n
