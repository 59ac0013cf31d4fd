"""Reference of :mod:`parcover_env.geometry.ray_kernels`' open-segment test
(:func:`~parcover_env.geometry.ray_kernels.open_segments_blocked`), per pair in plain numpy."""

from __future__ import annotations

import numpy as np


def blocked(a, b, walls) -> np.ndarray:
    """The open-segment test written out per pair (module docstring formulas), as the reference."""
    out = np.zeros(len(a), dtype=bool)
    for r in range(len(a)):
        d = b[r] - a[r]
        for x1, y1, x2, y2 in walls:
            e = np.array([x2 - x1, y2 - y1])
            w = np.array([x1, y1]) - a[r]
            den = d[0] * e[1] - d[1] * e[0]
            if abs(den) <= 1e-12:
                continue
            t = (w[0] * e[1] - w[1] * e[0]) / den
            u = (w[0] * d[1] - w[1] * d[0]) / den
            out[r] |= bool(0.0 < t < 1.0 and -1e-12 <= u <= 1.0 + 1e-12)
    return out
