"""Localize one robot's 360-degree sonar scan on the known map, its teammates drawn in (Kim, Pearce & Amato Fig. 6).

Used by the navigator (:mod:`parcover_env.expert.navigator`) after each stop-and-scan. The localizer
(:func:`parcover_env.localization.sonar.localizer.localize`) sees teammates as unknown obstacles and
its own success test rejects good poses next to them; so a pose is also accepted when the scan
matches the synthetic scan of the known map *with the other robots' discs at their beliefs*
(``NavigatorConfig.accept_error``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from parcover_env.config import Scenario
from parcover_env.expert.config import NavigatorConfig
from parcover_env.localization.sonar.known_map import known_map_features
from parcover_env.localization.sonar.localizer import Ellipse, LocalizationResult, localize, scan_error
from parcover_env.localization.sonar.params import SonarLocalizerParams
from parcover_env.localization.sonar.teammates import teammate_mask
from parcover_env.sensors.sonar import simulate_beams
from parcover_env.world.map_model import MapModel

__all__ = ["TeamFix", "TeamLocalizer", "shift_sensitivity", "teammate_mask"]


@dataclass(frozen=True)
class TeamFix:
    """Outcome of one localization: the localizer's result, the scan error against the map with the
    teammates in it (m, inf without a pose), and whether the pose is accepted."""

    result: LocalizationResult
    team_error: float
    ok: bool


class TeamLocalizer:
    """The known map's features and sectors (cached per map) and the acceptance rule of a fix."""

    def __init__(self, scenario: Scenario, cfg: NavigatorConfig, localizer: SonarLocalizerParams):
        self.cfg, self.loc = cfg, localizer
        self.sonar = scenario.robot.sonar
        self.radius = scenario.robot.radius
        self.map, self.features, self.sectors = known_map_features(
            scenario.map, self.sonar.range_max, cfg.sector_rule)
        self.n_bins = round(360.0 / self.sonar.scan_step_deg)
        self.scan_angles = np.radians(np.arange(self.n_bins) * self.sonar.scan_step_deg)

    def team_map(self, others: np.ndarray) -> MapModel:
        """The known map with the teammates as 16-gon obstacles at their believed positions."""
        if len(others) == 0 or not self.cfg.teammates_in_map:
            return self.map
        discs = shapely.union_all([shapely.Point(*q).buffer(self.radius, quad_segs=4) for q in others])
        free = self.map.free.difference(discs)
        return self.map if free.is_empty else MapModel(free=free, bounds=self.map.bounds)

    def shifted_errors(self, ranges: np.ndarray, pose: np.ndarray, others: np.ndarray, step: float,
                       n_dirs: int = 8) -> np.ndarray:
        """Scan errors ``(1 + n_dirs,)`` of the binned scan ``ranges`` against the known map's synthetic
        scans (teammates at ``others``) from ``pose`` and from ``pose`` shifted by ``step`` (m) in
        ``n_dirs`` directions, heading kept (see :func:`shift_sensitivity`)."""
        ang = np.arange(n_dirs) * (2 * math.pi / n_dirs)
        origins = np.vstack([pose[:2], pose[:2] + step * np.c_[np.cos(ang), np.sin(ang)]])
        axes = np.broadcast_to(pose[2] + self.scan_angles, (len(origins), len(self.scan_angles)))
        synth = simulate_beams(self.sonar, origins, np.ascontiguousarray(axes), self.map.segments,
                               np.asarray(others, dtype=float).reshape(-1, 2), self.radius,
                               np.full(len(origins), -1))
        return scan_error(ranges, synth, self.loc.error_clip)

    def localize(self, ranges: np.ndarray, ellipse: Ellipse, others: np.ndarray,
                 heading: float | None = None, heading_tol: float | None = None,
                 others_sigma: np.ndarray | None = None) -> TeamFix:
        """Localize the binned scan ``ranges`` (one per ``scan_angles``) inside ``ellipse``;
        ``others`` ``(M, 2)`` are the teammates' believed positions; ``heading`` the odometry heading
        (a prior against symmetric look-alikes), ``heading_tol`` the localizer's tolerance around it
        (rad; default ``heading_prior_tol_deg``). ``others_sigma`` ``(M,)``: the teammates' position
        uncertainty (m); if given, a pose is also accepted when the scan matches the known map on the
        readings no teammate can block (:func:`teammate_mask`, ``NavigatorConfig.mask_sigmas``)."""
        res = localize(ranges, self.scan_angles, self.team_map(others), self.sectors, ellipse, self.loc,
                       sonar=self.sonar, features=self.features, heading=heading, heading_tol=heading_tol)
        team_error = math.inf
        if res.pose is not None:
            axes = (res.pose[2] + self.scan_angles)[None, :]
            synth = simulate_beams(self.sonar, res.pose[None, :2], axes, self.map.segments, others,
                                   self.radius, np.array([-1]))
            team_error = float(scan_error(ranges, synth, self.loc.error_clip)[0])
        ok = res.pose is not None and (res.success or team_error <= self.cfg.accept_error)
        if res.pose is not None and not ok and others_sigma is not None and len(others):
            reach = self.radius + self.cfg.mask_sigmas * np.asarray(others_sigma, dtype=float)
            synth = simulate_beams(self.sonar, res.pose[None, :2], (res.pose[2] + self.scan_angles)[None, :],
                                   self.map.segments, np.zeros((0, 2)), 0.0, np.array([-1]))[0]
            keep = ~teammate_mask(res.pose, self.scan_angles, ranges, synth, np.asarray(others, dtype=float), reach)
            if keep.mean() >= self.cfg.min_unmasked_share:
                masked = float(scan_error(ranges[keep], synth[keep], self.loc.error_clip, self.loc.error_trim)[0])
                ok = masked <= self.cfg.accept_error
        return TeamFix(res, team_error, bool(ok))


def shift_sensitivity(errors: np.ndarray) -> float:
    """How well a scan pins a pose down: ``errors`` ``(1 + K,)`` are the scan errors at the pose and
    at K shifts of it by the same distance in K directions; returns the smallest increase (m). A
    scan along a straight corridor matches almost as well shifted along it (small increase): such a
    fix is not informative along the corridor, whatever its own error says."""
    e = np.asarray(errors, dtype=float)
    return float(np.min(e[1:]) - e[0])
