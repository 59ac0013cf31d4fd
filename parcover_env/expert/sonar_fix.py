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

from parcover_env.config import SonarFixConfig
from parcover_env.geometry import wrap_angle
from parcover_env.geometry.poses import compose, inverse
from parcover_env.localization.sonar.scan import ScanCollector

__all__ = ["SonarFixer"]


@dataclass
class _State:
    correction: np.ndarray
    scan: ScanCollector | None = None
    scan_odom: np.ndarray | None = None
    driven_since_scan: float = math.inf
    driven_since_fix: float = 0.0
    """Distance driven since the last absolute fix, Kinect or accepted sonar fix (m): bounds how far
    odometry can have drifted."""


class SonarFixer:
    """Per-robot sonar localization on demand, for the scripted expert's stale leaders."""

    def __init__(self, scenario, beam_angles: np.ndarray, control_dt: float, config: SonarFixConfig | None = None):
        from parcover_env.localization.sonar.known_map import known_map_features

        self.cfg = cfg = config if config is not None else scenario.expert.sonar_fix
        self.sonar = scenario.robot.sonar
        self.map, self.features, self.sectors = known_map_features(scenario.map, self.sonar.range_max)
        self.params = scenario.sonar_localizer
        self.beams = np.asarray(beam_angles, dtype=float)
        self.n_bins = int(round(360.0 / self.sonar.scan_step_deg))
        self.angles = np.arange(self.n_bins) * (2 * math.pi / self.n_bins)
        self.dt = control_dt
        self.scan_rate = min(cfg.scan_rate, scenario.robot.max_turn_rate)
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
             is_leader: bool, at_end: bool = False) -> tuple[float, float] | None:
        """Advance this robot's scan logic; returns a (v, w) command while it is scanning. ``at_end``:
        the robot believes it is at its route's end, where it checks its pose with a scan sooner
        (``final_rescan_distance``), since nothing later would catch a drifted arrival."""
        st = self.states.setdefault(agent, _State(np.zeros(3)))
        if fix_age < 2 * self.dt:  # a fresh Kinect fix: the odometry pose is absolute again
            st.correction, st.scan, st.driven_since_scan, st.driven_since_fix = np.zeros(3), None, math.inf, 0.0
            return None
        st.driven_since_scan += abs(speed) * self.dt
        st.driven_since_fix += abs(speed) * self.dt
        if st.scan is None:
            rescan = self.cfg.final_rescan_distance if at_end else self.cfg.rescan_distance
            if not (is_leader and fix_age > self.cfg.stale_after and st.driven_since_scan >= rescan):
                return None
            st.scan = ScanCollector(self.beams, self.n_bins, self.sonar.range_max, float(odom[2]))
            st.scan_odom = odom.copy()
            self.stats["sonar_scans"] += 1
        if not st.scan.add(float(odom[2]), ranges):
            return 0.0, self.scan_rate
        self._localize(st)
        st.scan, st.driven_since_scan = None, 0.0
        return None

    def gate(self, driven: float) -> tuple[float, float]:
        """(distance in m, heading in rad) within which a fix of the odometry pose is believed, after
        ``driven`` metres since the last Kinect fix: odometry drifts by a few percent of the distance
        driven, so a fix farther away is a false match."""
        c = self.cfg
        return (c.gate_distance + c.gate_distance_rate * driven,
                math.radians(c.gate_heading_deg + c.gate_heading_rate_deg * driven))

    def accept(self, fix: np.ndarray, prior: np.ndarray, driven: float) -> bool:
        """Whether the sonar ``fix`` (x, y, theta) is believable as a correction of ``prior``."""
        dist, turn = self.gate(driven)
        return bool(np.hypot(*(fix[:2] - prior[:2])) <= dist and abs(wrap_angle(fix[2] - prior[2])) <= turn)

    def _localize(self, st: _State) -> None:
        from parcover_env.localization.sonar import Ellipse, localize

        prior = compose(st.correction, st.scan_odom)
        ell = Ellipse(prior[:2], (self.gate(st.driven_since_fix)[0],) * 2, 0.0)
        res = localize(st.scan.ranges, self.angles, self.map, self.sectors, ell, self.params, sonar=self.sonar,
                       features=self.features, heading=float(prior[2]))
        if res.pose is not None and res.success and self.accept(res.pose, prior, st.driven_since_fix):
            st.correction = compose(res.pose, inverse(st.scan_odom))
            st.driven_since_fix = 0.0
            self.stats["sonar_localized"] += 1
        else:
            self.stats["sonar_failed"] += 1
