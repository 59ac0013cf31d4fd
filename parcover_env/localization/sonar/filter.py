"""The paper's minimal sonar noise filter (Kim, Pearce & Amato Fig. 11).

Starting from the nearest unprocessed reading MS, if a few readings around it lie on a line L, walk
left then right: every neighbour reading farther than the current one is moved onto L (sonar faults
are mostly too long: multipath on slanted walls), until a neighbour is not farther. Repeated
``repeats`` times (3-5 in the paper, more robots showing up as extra close walls need more).

Moving onto L only ever shortens a reading: where L's extension lies behind the reading (past a
concave corner, the next wall is nearer than L's extension) the walk stops, so corners (the
localizer's features) are kept. The paper is silent on this case; its premise is the same
("faulty data is usually farther than the actual range").
"""

from __future__ import annotations

import numpy as np

from parcover_env.localization.sonar import scan_kernels

__all__ = ["filter_scan"]


def filter_scan(ranges, angles, range_max: float, repeats: int = 4, half_window: int = 1,
                line_tol: float = 0.03) -> np.ndarray:
    """Filtered copy of a circular scan ``ranges (n,)`` at robot-frame ``angles (n,)`` (Fig. 11)."""
    r = np.array(ranges, dtype=float)
    a = np.asarray(angles, dtype=float)
    if r.ndim != 1 or r.shape != a.shape or len(r) < 2 * half_window + 3:
        raise ValueError(f"ranges and angles must be equal-length 1-D arrays, got {r.shape}, {a.shape}")
    if repeats < 1 or half_window < 1:
        raise ValueError(f"repeats and half_window must be >= 1, got {repeats}, {half_window}")
    return scan_kernels.filter_scan(np.ascontiguousarray(r), np.ascontiguousarray(np.sin(a)),
                                    np.ascontiguousarray(np.cos(a)), float(range_max), int(repeats), int(half_window),
                                    float(line_tol))
