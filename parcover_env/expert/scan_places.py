"""Where along its route a robot's next sonar scan can pin its pose down (Kim, Pearce & Amato: scan
where the scan works well).

The env's sonar service refuses a fix whose scan does not pin the pose down (``observation.scan.shift_test``:
the scan matches the known map about as well from the pose shifted by ``shift_test``), e.g. along a
straight corridor or in open space, and reports it as uninformative. A scan from the same spot will not
do better, so the expert predicts where one would: :meth:`ScanPlaces.informative` runs the same shift
test on the known map's noise-free synthetic scan from a candidate pose (no teammates, a prediction
from the map alone), and :meth:`ScanPlaces.ahead` / :meth:`ScanPlaces.behind` return the first
candidate along the robot's route, every ``sample`` metres, that passes it.
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from parcover_env.config import Scenario
from parcover_env.geometry import segments_blocked
from parcover_env.localization.sonar.config import sonar_localizer_config
from parcover_env.localization.sonar.localizer import synthetic_scans
from parcover_env.localization.sonar.pin_down import shift_increase, shifted_errors
from parcover_env.sensors.sonar import SonarRing

__all__ = ["ScanPlaces"]


class ScanPlaces:
    """The shift test of the env's sonar service (``observation.scan``) predicted on the known map
    ``segments (S, 4)`` for the scenario's sonar; ``sample``: spacing of the candidates along a route (m)."""

    def __init__(self, scenario: Scenario, segments: np.ndarray, sample: float = 0.1):
        scan = scenario.observation.scan
        self.step, self.threshold = float(scan.shift_test), float(scan.min_shift_increase)
        params = sonar_localizer_config(scenario)
        self.clip, self.trim = params.error_clip, params.error_trim
        self.sonar = scenario.robot.sonar
        self.segments = np.asarray(segments, dtype=float)
        self.angles = SonarRing(self.sonar).scan_angles  # the env's 360-degree scan
        self.sample = float(sample)

    def informative(self, pose: np.ndarray) -> bool:
        """Whether a scan from ``pose`` (x, y, theta) would pass the service's shift test on the known
        map: its noise-free synthetic scan matches worse by at least ``min_shift_increase`` from the pose
        shifted by ``shift_test`` in each of 8 directions. Always True with ``shift_test`` 0."""
        if self.step <= 0:
            return True
        pose = np.asarray(pose)  # synthetic_scans and shifted_errors compute in float
        synth = synthetic_scans(pose, self.angles, self.segments, self.sonar)[0]
        errors = shifted_errors(synth, self.angles, pose, segments=self.segments, sonar=self.sonar,
                                others=np.zeros((0, 2)), radius=0.0, clip=self.clip, step=self.step, trim=self.trim)
        return shift_increase(errors) >= self.threshold

    def ahead(self, route: np.ndarray, progress: float, near: float, far: float) -> float | None:
        """The route distance (m) from arc length ``progress`` to the first informative place between
        ``near`` and ``far`` metres ahead along ``route (M, 2)`` (the route's end counts, however close
        it is then), or None."""
        line = shapely.LineString(route)
        end = line.length
        for d in np.arange(near, far + 1e-9, self.sample):
            s = min(progress + float(d), end)
            if self.informative(_pose_on(line, s, 1.0)):
                return s - progress
            if s >= end:
                return None
        return None

    def behind(self, route: np.ndarray, xy: np.ndarray, near: float, far: float) -> np.ndarray | None:
        """The first informative place (x, y) between ``near`` and ``far`` metres back from the end of
        ``route (M, 2)`` that the robot at ``xy`` sees (no wall of the known map between), or None."""
        found = self.behind_at(route, xy, near, far)
        return None if found is None else found[0]

    def behind_at(self, route: np.ndarray, xy: np.ndarray, near: float,
                  far: float) -> tuple[np.ndarray, float] | None:
        """:meth:`behind`'s place and how far back from the route's end it lies (m), or None."""
        line = shapely.LineString(route)
        end = line.length
        for d in np.arange(near, far + 1e-9, self.sample):
            s = end - float(d)
            if s <= 0:
                return None
            pose = _pose_on(line, s, -1.0)
            if segments_blocked(xy, pose[:2], self.segments)[0]:
                return None
            if self.informative(pose):
                return pose[:2], float(d)
        return None


def _pose_on(line: shapely.LineString, s: float, sign: float) -> np.ndarray:
    """The pose at arc length ``s`` of ``line``, heading along it (``sign`` -1: back along it)."""
    p = line.interpolate(s)
    a, b = line.interpolate(max(s - 0.05, 0.0)), line.interpolate(min(s + 0.05, line.length))
    heading = math.atan2(sign * (b.y - a.y), sign * (b.x - a.x))
    return np.array([p.x, p.y, heading])
