"""Angles and planar rotations: the package's one angle-wrapping convention, (-pi, pi]."""

from __future__ import annotations

import numpy as np

__all__ = ["wrap_angle", "rotate"]


def wrap_angle(a):
    """Wrap angles to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(a, dtype=float), 2.0 * np.pi)


def rotate(v: np.ndarray, theta) -> np.ndarray:
    """Rotate vectors ``v (..., 2)`` by ``theta`` (broadcast)."""
    c, s = np.cos(theta), np.sin(theta)
    x, y = v[..., 0], v[..., 1]
    return np.stack([c * x - s * y, s * x + c * y], axis=-1)
