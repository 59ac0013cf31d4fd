"""Simple reference policies acting from observations only: random and waypoint-seeking."""

from __future__ import annotations

import numpy as np

from parcover_env.envs.observations import ObservationLayout
from parcover_env.geometry import atan2
from parcover_env.policies.protocol import Policy

__all__ = ["RandomPolicy", "WaypointPolicy"]


class RandomPolicy(Policy):
    """Uniform random actions in [-1, 1]^2 from its own seeded generator."""

    def __init__(self, seed: int | None = None):
        self.rng = np.random.default_rng(seed)

    def act(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {a: self.rng.uniform(-1.0, 1.0, 2).astype(np.float32) for a in sorted(observations)}


class WaypointPolicy(Policy):
    """Every robot drives to the waypoint in its observation (``goal_dx, goal_dy``), independently.

    Unicycle go-to-goal: turn rate proportional to the bearing, speed reduced when the goal is off
    the heading. No formation, no avoidance: the baseline that the scripted expert must beat.
    """

    def __init__(self, layout: ObservationLayout, k_v: float = 2.0, k_w: float = 2.0):
        self.layout, self.k_v, self.k_w = layout, k_v, k_w

    def act(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        out = {}
        for agent, obs in observations.items():
            dx = float(self.layout.get(obs, "goal_dx")[0])
            dy = float(self.layout.get(obs, "goal_dy")[0])
            bearing = atan2(dy, dx)
            dist = np.hypot(dx, dy)
            v = np.clip(self.k_v * dist, 0.0, 1.0) * max(np.cos(bearing), 0.0) ** 2
            w = np.clip(self.k_w * bearing, -1.0, 1.0)
            out[agent] = np.array([v, w], dtype=np.float32)
        return out
