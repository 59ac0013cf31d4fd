"""Per-agent observation vector: a named, fixed layout with physical bounds (SI units)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from parcover_env.geometry import atan2

__all__ = ["ObservationLayout", "MAX_FIX_AGE", "SCALAR_ENTRIES", "ellipse_entries"]

MAX_FIX_AGE = 60.0
"""Seconds since the last absolute pose fix are reported capped at this value."""


SCALAR_ENTRIES = ("x", "y", "cos_theta", "sin_theta", "v", "omega", "leader", "slot", "fix_age", "sigma_major",
                  "sigma_minor", "sigma_axis_cos2", "sigma_axis_sin2", "sigma_heading", "goal_dx", "goal_dy",
                  "pred_dx", "pred_dy", "pred_cos", "pred_sin", "pred_visible", "kpois_visited", "time")
"""The one-column entries :meth:`ObservationLayout.fill_scalars` writes (all but the sonar)."""


def ellipse_entries(cov: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Pose covariances ``(N, 3, 3)`` -> ``(N, 5)``: sigma_major, sigma_minor (m), the major axis'
    doubled angle in the robot frame as (cos 2a, sin 2a) (an axis has no sign; (1, 0) for a
    circle), and the heading sigma (rad). ``heading``: the estimated headings ``(N,)``."""
    a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    mean, half = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
    two_a = np.where(half <= 1e-9 * mean, 0.0, atan2(2.0 * b, a - c) - 2.0 * heading)
    return np.stack([np.sqrt(np.maximum(mean + half, 0.0)), np.sqrt(np.maximum(mean - half, 0.0)),
                     np.cos(two_a), np.sin(two_a), np.sqrt(np.maximum(cov[:, 2, 2], 0.0))], axis=1)


@dataclass(frozen=True)
class ObservationLayout:
    """Names, slices and bounds of the entries of one agent's observation."""

    names: tuple[str, ...]
    slices: dict[str, slice]
    low: np.ndarray
    high: np.ndarray

    @classmethod
    def build(cls, bounds, max_speed: float, max_turn_rate: float, n_sonar: int,
              sonar_max: float, pred_range: float, covariance: bool = False) -> ObservationLayout:
        """The layout; ``covariance`` adds the pose-uncertainty entries after ``fix_age``."""
        x0, y0, x1, y1 = bounds
        diag = float(np.hypot(x1 - x0, y1 - y0))
        m = 1.0  # estimates may drift off the floor a little: clipped to the map box +- 1 m
        entries = [
            ("x", 1, x0 - m, x1 + m), ("y", 1, y0 - m, y1 + m),
            ("cos_theta", 1, -1.0, 1.0), ("sin_theta", 1, -1.0, 1.0),
            ("v", 1, -max_speed, max_speed), ("omega", 1, -max_turn_rate, max_turn_rate),
            ("leader", 1, 0.0, 1.0), ("slot", 1, 0.0, 1.0), ("fix_age", 1, 0.0, MAX_FIX_AGE),
            *([("sigma_major", 1, 0.0, diag), ("sigma_minor", 1, 0.0, diag),
               ("sigma_axis_cos2", 1, -1.0, 1.0), ("sigma_axis_sin2", 1, -1.0, 1.0),
               ("sigma_heading", 1, 0.0, np.pi)] if covariance else []),
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
        """Clip ``(N, D)`` observations into the bounds in place (NaN stays NaN, as with ``np.clip``)."""
        return np.minimum(np.maximum(obs, self.low, out=obs), self.high, out=obs)

    def fill_scalars(self, obs: np.ndarray, est: np.ndarray, velocity: np.ndarray, leader: np.ndarray,
                     slot: np.ndarray, fix_age: np.ndarray, covariance: np.ndarray, goals: np.ndarray,
                     rel_xy: np.ndarray, rel_heading: np.ndarray, visible: np.ndarray, kpois_visited: float,
                     time: float) -> None:
        """Write the :data:`SCALAR_ENTRIES` of every robot's row of ``obs (N, D)`` in one compiled
        pass: pose estimate ``est (N, 3)``, ``velocity (N, 2)`` (v, omega), leader flags, formation
        slots (scaled by ``N - 1``), seconds since the last fix (capped at :data:`MAX_FIX_AGE`), the
        ellipse of ``covariance (N, 3, 3)`` (:func:`ellipse_entries`), the lookahead ``goals (N, 2)``
        in the robot frame, the follower camera's reading, and two team-wide fractions."""
        from parcover_env.envs import _step_kernels

        n = len(obs)
        _step_kernels.scalar_entries(obs, self._columns(), est, velocity, leader, slot, max(n - 1, 1), fix_age,
                                     MAX_FIX_AGE, covariance, goals, rel_xy, rel_heading, visible, float(kpois_visited),
                                     float(time))

    def _columns(self) -> np.ndarray:
        cols = self.__dict__.get("_cols")
        if cols is None:  # frozen dataclass: cache by the back door
            cols = np.array([self.slices[k].start if k in self.slices else -1 for k in SCALAR_ENTRIES], np.int64)
            object.__setattr__(self, "_cols", cols)
        return cols

    def get(self, obs: np.ndarray, name: str) -> np.ndarray:
        """The entry ``name`` of one observation ``(D,)`` or a batch ``(N, D)``."""
        return obs[..., self.slices[name]]
