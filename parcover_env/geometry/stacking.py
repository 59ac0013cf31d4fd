"""Gathering the per-world arrays of ``K`` worlds into one ``(K, ...)`` block, cheaply for ``K = 1``
(the single env steps through the same block code, one world at a time)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["stack"]


def stack(arrays: Sequence[np.ndarray], copy: bool = False) -> np.ndarray:
    """``np.stack(arrays)``; for one array a ``(1, ...)`` view of it (a copy with ``copy``), which
    skips ``np.stack``'s few microseconds of dispatch."""
    if len(arrays) == 1:
        one = np.asarray(arrays[0])[None]
        return one.copy() if copy else one
    return np.stack(arrays)
