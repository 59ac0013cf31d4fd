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

__all__ = ["filter_scan"]


def _fit_line(pts: np.ndarray) -> tuple[np.ndarray, float, float]:
    centre = pts.mean(axis=0)
    _, s, vt = np.linalg.svd(pts - centre)
    normal = vt[1]
    if normal @ centre < 0:
        normal = -normal
    return normal, float(normal @ centre), float(s[1] / np.sqrt(len(pts)))


def filter_scan(ranges, angles, range_max: float, repeats: int = 4, half_window: int = 1,
                line_tol: float = 0.03) -> np.ndarray:
    """Filtered copy of a circular scan ``ranges (n,)`` at robot-frame ``angles (n,)`` (Fig. 11)."""
    r = np.array(ranges, dtype=float)
    a = np.asarray(angles, dtype=float)
    if r.ndim != 1 or r.shape != a.shape or len(r) < 2 * half_window + 3:
        raise ValueError(f"ranges and angles must be equal-length 1-D arrays, got {r.shape}, {a.shape}")
    if repeats < 1 or half_window < 1:
        raise ValueError(f"repeats and half_window must be >= 1, got {repeats}, {half_window}")
    n = len(r)
    done = np.zeros(n, dtype=bool)
    u = np.stack([np.cos(a), np.sin(a)], axis=1)
    for _ in range(repeats):
        free = np.nonzero(~done & (r < range_max))[0]
        if len(free) == 0:
            break
        ms = int(free[np.argmin(r[free])])
        done[ms] = True
        idx = [(ms + k) % n for k in range(-half_window, half_window + 1)]
        if np.any(r[idx] >= range_max):
            continue
        normal, dist, rms = _fit_line(r[idx, None] * u[idx])
        if rms > line_tol:
            continue
        for step in (-1, 1):
            cur = ms
            for _ in range(n - 1):
                nxt = (cur + step) % n
                if nxt == ms or r[nxt] <= r[cur]:
                    break
                cos = float(u[nxt] @ normal)
                if cos <= 0.05 or dist / cos > range_max or dist / cos > r[nxt] + line_tol:
                    break  # L runs behind the reading: a nearer surface (the next wall of a corner)
                r[nxt] = dist / cos
                done[nxt] = True
                cur = nxt
    return r
