"""Planar pose algebra on (x, y, theta) arrays."""

from __future__ import annotations

import math

import numpy as np

from parcover_env.geometry.angles import wrap_angle

__all__ = ["compose", "inverse"]


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose composition a o b of (x, y, theta)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], float(wrap_angle(a[2] + b[2]))])


def inverse(a: np.ndarray) -> np.ndarray:
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([-(c * a[0] + s * a[1]), s * a[0] - c * a[1], -a[2]])
