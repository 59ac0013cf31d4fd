"""Sonar fixes for robots out of Kinect view (``localization: both``).

A leader whose last absolute fix is older than ``stale_after`` stops and turns in place while its
sonar ring sweeps the 5-degree bins of a 360-degree scan (seed B: rotate and scan), then localizes
with the relaxed-sector feature localizer on the known map. A fix becomes a correction on top of
the robot's odometry pose: ``belief = fix o odom_at_scan^-1 o odom``. A new Kinect fix (the env's
estimate becomes absolute again) clears the correction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from parcover_env.geometry import wrap_angle

__all__ = ["ScanCollector", "SonarFixer", "compose", "inverse"]


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose composition a o b of (x, y, theta)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], float(wrap_angle(a[2] + b[2]))])


def inverse(a: np.ndarray) -> np.ndarray:
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([-(c * a[0] + s * a[1]), s * a[0] - c * a[1], -a[2]])


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


@dataclass
class _State:
    correction: np.ndarray
    scan: ScanCollector | None = None
    scan_odom: np.ndarray | None = None
    driven_since_scan: float = math.inf
    driven_since_fix: float = 0.0
    """Distance driven since the last Kinect fix (m): bounds how far odometry can have drifted."""


class SonarFixer:
    """Per-robot sonar localization on demand, for the scripted expert's stale leaders."""

    def __init__(self, scenario, beam_angles: np.ndarray, control_dt: float, stale_after: float = 8.0,
                 rescan_distance: float = 2.0, scan_rate: float = 0.6):
        from parcover_env.expert.navigator import known_map_features
        from parcover_env.localization.sonar import SonarLocalizerParams

        self.sonar = scenario.robot.sonar
        self.map, self.features, self.sectors = known_map_features(scenario.map, self.sonar.range_max)
        self.params = SonarLocalizerParams()
        self.beams = np.asarray(beam_angles, dtype=float)
        self.n_bins = int(round(360.0 / self.sonar.scan_step_deg))
        self.angles = np.arange(self.n_bins) * (2 * math.pi / self.n_bins)
        self.dt = control_dt
        self.stale_after, self.rescan_distance = stale_after, rescan_distance
        self.scan_rate = min(scan_rate, scenario.robot.max_turn_rate)
        self.growth = (0.1, 0.05)  # ellipse axis growth: m per m travelled, m per rad turned
        self.states: dict[str, _State] = {}
        self.stats = {"sonar_scans": 0, "sonar_localized": 0, "sonar_failed": 0}

    def corrected(self, agent: str) -> bool:
        """Whether a sonar fix currently corrects this robot's odometry."""
        st = self.states.get(agent)
        return st is not None and bool(np.any(st.correction != 0.0))

    def belief(self, agent: str, odom: np.ndarray) -> np.ndarray:
        st = self.states.get(agent)
        return odom if st is None else compose(st.correction, odom)

    def step(self, agent: str, odom: np.ndarray, fix_age: float, speed: float, ranges: np.ndarray,
             is_leader: bool) -> tuple[float, float] | None:
        """Advance this robot's scan logic; returns a (v, w) command while it is scanning."""
        st = self.states.setdefault(agent, _State(np.zeros(3)))
        if fix_age < 2 * self.dt:  # a fresh Kinect fix: the odometry pose is absolute again
            st.correction, st.scan, st.driven_since_scan, st.driven_since_fix = np.zeros(3), None, math.inf, 0.0
            return None
        st.driven_since_scan += abs(speed) * self.dt
        st.driven_since_fix += abs(speed) * self.dt
        if st.scan is None:
            if not (is_leader and fix_age > self.stale_after and st.driven_since_scan >= self.rescan_distance):
                return None
            st.scan = ScanCollector(self.beams, self.n_bins, self.sonar.range_max, float(odom[2]))
            st.scan_odom = odom.copy()
            self.stats["sonar_scans"] += 1
        if not st.scan.add(float(odom[2]), ranges):
            return 0.0, self.scan_rate
        self._localize(st)
        st.scan, st.driven_since_scan = None, 0.0
        return None

    def _localize(self, st: _State) -> None:
        from parcover_env.localization.sonar import Ellipse, localize

        prior = compose(st.correction, st.scan_odom)
        # odometry drifts by a few percent of the distance driven: a fix outside that is a false match
        axis = 0.15 + self.growth[0] * st.driven_since_fix
        ell = Ellipse(prior[:2], (axis, axis), 0.0)
        res = localize(st.scan.ranges, self.angles, self.map, self.sectors, ell, self.params, sonar=self.sonar,
                       features=self.features)
        if res.pose is not None and res.success and np.hypot(*(res.pose[:2] - prior[:2])) <= axis:
            st.correction = compose(res.pose, inverse(st.scan_odom))
            self.stats["sonar_localized"] += 1
        else:
            self.stats["sonar_failed"] += 1
