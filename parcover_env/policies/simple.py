"""Simple reference policies acting from observations only: random and waypoint-seeking."""

from __future__ import annotations

import numpy as np

from parcover_env.envs.observations import ObservationLayout
from parcover_env.geometry import atan2
from parcover_env.localization.sonar.config import SonarLocalizerConfig
from parcover_env.policies.protocol import Policy

__all__ = ["RandomPolicy", "WaypointPolicy", "default_scan_sigma"]


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

    With the env's sonar localization service (``observation.scan``: the observation has a
    ``scanning`` entry and the action a ``scan`` component), a robot stops and scans when its
    uncertainty ellipse's major axis ``sigma_major`` exceeds ``scan_sigma`` (m). After a scan without
    a fix (``scan_result`` < 0: rejected -1 or uninformative -0.5) it scans again at once, up to
    ``retries`` times in a row (the env searches a wider region after each rejection,
    ``observation.scan.miss_inflation``); after that it scans again only once ``sigma_major`` has
    grown ``retry_growth`` times its value at the last scan (it has driven on, so the next scan sees
    another place). ``scan_sigma`` defaults to
    :func:`default_scan_sigma`; ``retries`` = 2 as the scripted expert's ``refused_rescans``.
    """

    def __init__(self, layout: ObservationLayout, k_v: float = 2.0, k_w: float = 2.0,
                 scan_sigma: float | None = None, retry_growth: float = 1.5, retries: int = 2):
        self.layout, self.k_v, self.k_w = layout, k_v, k_w
        self.width = 3 if "scanning" in layout.slices else 2
        """Action components: 3 with the env's sonar localization service (the ``scan`` component)."""
        self.scans = self.width == 3 and "sigma_major" in layout.slices
        """Scans when due; without the ``sigma_*`` entries (``observation.pose_covariance`` off, as in
        the ``ideal`` preset) it never asks for a scan (its ``scan`` component stays -1)."""
        self.scan_sigma = default_scan_sigma() if scan_sigma is None else float(scan_sigma)
        self.retry_growth, self.retries = float(retry_growth), int(retries)
        self.rejected: dict[str, int] = {}
        self.retry_at: dict[str, float] = {}
        self.was_scanning: dict[str, bool] = {}
        self.started: dict[str, float] = {}
        self.n_scans = 0

    def reset(self, observations=None) -> None:
        self.retry_at, self.was_scanning, self.started, self.rejected, self.n_scans = {}, {}, {}, {}, 0

    def stats(self) -> dict:
        return {"scans": self.n_scans} if self.scans else {}

    def act(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        out = {}
        for agent, obs in observations.items():
            dx = float(self.layout.get(obs, "goal_dx")[0])
            dy = float(self.layout.get(obs, "goal_dy")[0])
            bearing = atan2(dy, dx)
            dist = np.hypot(dx, dy)
            v = np.clip(self.k_v * dist, 0.0, 1.0) * max(np.cos(bearing), 0.0) ** 2
            w = np.clip(self.k_w * bearing, -1.0, 1.0)
            if not self.scans:
                out[agent] = np.array([v, w, -1.0][: self.width], dtype=np.float32)
                continue
            out[agent] = np.array([v, w, -1.0], dtype=np.float32)
            if self.scan_due(agent, obs):
                out[agent] = np.array([0.0, 0.0, 1.0], dtype=np.float32)
        return out

    def scan_due(self, agent: str, obs: np.ndarray) -> bool:
        """Whether ``agent`` starts a scan now (see the class docstring); tracks its scans' outcomes."""
        scanning = bool(self.layout.get(obs, "scanning")[0] > 0.5)
        sigma = float(self.layout.get(obs, "sigma_major")[0])
        if self.was_scanning.get(agent, False) and not scanning:  # a scan just ended
            rejected = float(self.layout.get(obs, "scan_result")[0]) < 0
            self.rejected[agent] = self.rejected.get(agent, 0) + 1 if rejected else 0
            self.retry_at[agent] = self.retry_growth * self.started[agent] if rejected else 0.0
        self.was_scanning[agent] = scanning
        if scanning:
            return False
        again = 0 < self.rejected.get(agent, 0) <= self.retries  # rejected: scan again at once
        if not again:
            if sigma <= max(self.scan_sigma, self.retry_at.get(agent, 0.0)):
                return False
            self.rejected[agent] = 0  # a new series of retries
        self.started[agent] = sigma
        self.n_scans += 1
        return True


def default_scan_sigma() -> float:
    """The ``sigma_major`` (m) above which :class:`WaypointPolicy` scans: the sonar localizer's
    documented candidate tolerance ``ellipse_distance`` (a feature pose farther than this outside
    the searched region is dropped) over the ``covariance_sigmas`` its region spans
    (:class:`~parcover_env.localization.sonar.config.SonarLocalizerConfig` defaults: 0.3 m / 2 =
    0.15 m): the robot scans while a drift of two sigmas is still within what the localizer tolerates."""
    cfg = SonarLocalizerConfig()
    return cfg.ellipse_distance / cfg.covariance_sigmas
