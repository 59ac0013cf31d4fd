"""Episode metrics, reported in ``info[agent]["episode"]`` when the episode ends."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

__all__ = ["EpisodeMetrics"]


@dataclass
class EpisodeMetrics:
    n_kpois: int
    n_robots: int
    c_max: float
    """PPCP lower bound: shortest-path length to the furthest KPOI (m)."""
    max_speed: float
    steps: int = 0
    time: float = 0.0
    kpois_visited: int = 0
    makespan: float | None = None
    """Time when the last KPOI was visited (s); None if the mission was not completed."""
    wall_collisions: int = 0
    robot_collisions: int = 0
    path_lengths: list[float] = field(default_factory=list)
    localization_error: float = 0.0
    """RMS distance between the observed pose estimates and the true poses (m)."""
    messages: dict[str, int] = field(default_factory=dict)
    _sq_err: float = 0.0
    _n_err: int = 0

    def record_step(self, time: float, kpois_visited: int, true_poses: np.ndarray,
                    est_poses: np.ndarray, wall: int, robot: int) -> None:
        self.steps += 1
        self.time = time
        self.kpois_visited = kpois_visited
        self.wall_collisions += wall
        self.robot_collisions += robot
        err = true_poses[:, :2] - est_poses[:, :2]
        self._sq_err += float(np.sum(err * err))
        self._n_err += len(err)
        self.localization_error = float(np.sqrt(self._sq_err / max(self._n_err, 1)))

    def summary(self) -> dict:
        """Plain-dict summary (JSON-friendly)."""
        out = {k: v for k, v in asdict(self).items() if not k.startswith("_")}
        out["success"] = self.kpois_visited == self.n_kpois
        bound = self.c_max / self.max_speed if self.c_max > 0 else float("nan")
        out["makespan_ratio"] = (self.makespan / bound) if self.makespan is not None else None
        out["collisions"] = self.wall_collisions + self.robot_collisions
        return out
