"""Readings of a 360-degree sonar scan that a teammate may explain (robots are not in the known map)."""

from __future__ import annotations

import numpy as np

__all__ = ["teammate_mask"]


def teammate_mask(pose: np.ndarray, scan_angles: np.ndarray, ranges: np.ndarray, expected: np.ndarray,
                  others: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """``(n,)`` True for the readings a teammate may explain: shorter than ``expected`` (the known
    map's synthetic scan from ``pose``) and ending within ``reach`` ``(M,)`` (m: the robot radius
    grown by the teammate's position uncertainty) of a teammate ``others (M, 2)``. ``scan_angles``
    are in the robot frame."""
    r = np.asarray(ranges, dtype=float)
    ang = pose[2] + np.asarray(scan_angles, dtype=float)
    ends = np.asarray(pose[:2], dtype=float) + r[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    gap = np.hypot(*(ends[:, None, :] - np.asarray(others, dtype=float)[None, :, :]).transpose(2, 0, 1))
    return (r < np.asarray(expected, dtype=float)) & np.any(gap <= np.asarray(reach, dtype=float)[None, :], axis=1)
