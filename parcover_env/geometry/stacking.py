"""Gathering the per-world arrays of ``K`` worlds into one ``(K, ...)`` block, cheaply for ``K = 1``
(the single env steps through the same block code, one world at a time)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["stack"]


def stack(arrays: Sequence[np.ndarray], copy: bool = False) -> np.ndarray:
    """``np.stack(arrays)``; for one array a ``(1, ...)`` view of it (a copy with ``copy``), which
    skips ``np.stack``'s few microseconds of dispatch. Arrays of one shape (at least 1-d) are joined
    end to end and reshaped, the same values at a third of ``np.stack``'s cost for 64 small ones."""
    if len(arrays) == 1:
        one = np.asarray(arrays[0])[None]
        return one.copy() if copy else one
    shape = np.shape(arrays[0]) if arrays else ()
    if shape and all(type(a) is np.ndarray and a.shape == shape for a in arrays):
        return np.concatenate(arrays).reshape(len(arrays), *shape)
    return np.stack(arrays)
