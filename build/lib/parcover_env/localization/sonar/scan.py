"""Assembling a 360-degree scan from ring readings taken while a robot turns in place."""

from __future__ import annotations

import math

import numpy as np

from parcover_env.geometry import wrap_angle

__all__ = ["ScanCollector"]


class ScanCollector:
    """Bins ring readings taken while turning in place into ``n_bins`` scan directions.

    Each bin keeps the reading whose beam direction (odometry heading + beam angle, relative to
    the heading at the start) is closest to the bin centre; the scan is complete when every bin
    holds a reading within ``tol`` of its centre, or after a full turn.
    """

    def __init__(self, beam_angles: np.ndarray, n_bins: int, range_max: float, start_heading: float,
                 tol_deg: float = 2.0):
        self.beams = np.asarray(beam_angles, dtype=float)
        self.n = n_bins
        self.step = 2 * math.pi / n_bins
        self.start = start_heading
        self.prev = start_heading
        self.turned = 0.0
        self.tol = math.radians(tol_deg)
        self.ranges = np.full(n_bins, float(range_max))
        self.offset = np.full(n_bins, np.inf)

    def add(self, heading: float, ranges: np.ndarray) -> bool:
        """Add one ring reading at odometry ``heading``; returns True when the scan is complete."""
        self.turned += abs(float(wrap_angle(heading - self.prev)))
        self.prev = heading
        rel = np.mod(heading - self.start + self.beams, 2 * math.pi) / self.step
        b = np.round(rel).astype(int) % self.n
        off = np.abs(rel - np.round(rel))
        for k in range(len(b)):  # each bin keeps its nearest-to-centre reading
            if off[k] < self.offset[b[k]]:
                self.offset[b[k]], self.ranges[b[k]] = off[k], ranges[k]
        return bool(np.all(self.offset * self.step <= self.tol)) or self.turned >= 2 * math.pi + self.step
