"""Per-agent observation vector: a named, fixed layout with physical bounds (SI units)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

__all__ = ["ObservationLayout", "MAX_FIX_AGE"]

MAX_FIX_AGE = 60.0
"""Seconds since the last absolute pose fix are reported capped at this value."""


@dataclass(frozen=True)
class ObservationLayout:
    """Names, slices and bounds of the entries of one agent's observation."""

    names: tuple[str, ...]
    slices: dict[str, slice]
    low: np.ndarray
    high: np.ndarray

    @classmethod
    def build(cls, bounds, max_speed: float, max_turn_rate: float, n_sonar: int,
              sonar_max: float, pred_range: float) -> ObservationLayout:
        x0, y0, x1, y1 = bounds
        diag = float(np.hypot(x1 - x0, y1 - y0))
        m = 1.0  # estimates may drift off the floor a little: clipped to the map box +- 1 m
        entries = [
            ("x", 1, x0 - m, x1 + m), ("y", 1, y0 - m, y1 + m),
            ("cos_theta", 1, -1.0, 1.0), ("sin_theta", 1, -1.0, 1.0),
            ("v", 1, -max_speed, max_speed), ("omega", 1, -max_turn_rate, max_turn_rate),
            ("leader", 1, 0.0, 1.0), ("slot", 1, 0.0, 1.0), ("fix_age", 1, 0.0, MAX_FIX_AGE),
            ("goal_dx", 1, -diag - 2 * m, diag + 2 * m), ("goal_dy", 1, -diag - 2 * m, diag + 2 * m),
            ("pred_dx", 1, -pred_range, pred_range), ("pred_dy", 1, -pred_range, pred_range),
            ("pred_cos", 1, -1.0, 1.0), ("pred_sin", 1, -1.0, 1.0), ("pred_visible", 1, 0.0, 1.0),
            ("kpois_visited", 1, 0.0, 1.0), ("time", 1, 0.0, 1.0),
            ("sonar", n_sonar, 0.0, sonar_max),
        ]
        names, slices, low, high, at = [], {}, [], [], 0
        for name, size, lo, hi in entries:
            if size == 0:
                continue
            names.append(name)
            slices[name] = slice(at, at + size)
            low += [lo] * size
            high += [hi] * size
            at += size
        return cls(tuple(names), slices, np.array(low, np.float32), np.array(high, np.float32))

    @property
    def size(self) -> int:
        return len(self.low)

    def space(self) -> spaces.Box:
        return spaces.Box(self.low, self.high, dtype=np.float32)

    def clip(self, obs: np.ndarray) -> np.ndarray:
        """Clip ``(N, D)`` observations into the bounds in place."""
        np.clip(obs, self.low, self.high, out=obs)
        return obs

    def get(self, obs: np.ndarray, name: str) -> np.ndarray:
        """The entry ``name`` of one observation ``(D,)`` or a batch ``(N, D)``."""
        return obs[..., self.slices[name]]
