"""The env's sonar localization service: Kim, Pearce & Amato's stop-scan-match as a fix source.

A robot asks for a scan with the ``scan`` action component (``observation.scan.enabled``): it is
held still (its commands zeroed) for :attr:`SonarFixes.duration_steps` control steps, the time the
real robot takes to turn in place at ``scan.turn_rate`` until its ring has read every 5-degree
direction of a 360-degree scan (72 readings; :func:`scan_turn`: the largest gap between neighbouring
transducers, 72 degrees for the AmigoBot ring, as the scripted expert's own scans turn). At the scan's
last step its scan of the true map is simulated (:meth:`~parcover_env.sensors.sonar.SonarRing.scan`,
the realistic sonar model, the episode's generator; the teammates are obstacles at their true
positions), and the paper's localizer (:func:`~parcover_env.localization.sonar.localizer.localize`)
matches it against the known map, the teammates drawn in at their *estimates*, inside the region of
the robot's own estimate and covariance (never its true pose). The fix is accepted when the
localizer succeeds (mean clipped scan error below ``sonar_localizer.success_error``, or that error on
the readings no teammate can explain, :meth:`SonarFixes.matches_unmasked`), the scan pins the pose
down (:meth:`SonarFixes.pins_down`: shifted by ``scan.shift_test`` it matches worse) and it lies inside the gate
(``scan.gate_sigmas`` of the widened position covariance, heading within the heading gate, at most
``scan.gate_heading_max_deg``); the
estimator then resets the robot's estimate to it with :attr:`SonarFixes.covariance`. A rejected scan
leaves the estimate and covariance as they were; unless the scan was merely uninformative (its pose
matched but did not pin the pose down), the robot's next scan searches a region whose sigmas are
``scan.miss_inflation`` times wider (at most ``scan.max_inflation``), until a fix. A fix found there
but outside the gate of the estimate's own covariance is, with ``scan.confirm_widened``, held, not applied:
a region several metres across holds look-alike places of the map. It is applied when a later scan,
taken at least ``scan.shift_test`` from where the held one was (a scan from the same spot repeats a
look-alike match), finds a fix that agrees with it (:meth:`SonarFixes.confirmed`).

Each scan's outcome (the ``scan_result`` entry and ``info[agent]["sonar_fix"]``) tells a policy what
to do next: :data:`ACCEPTED` (the estimate was reset), :data:`HELD` (a fix awaits a confirming scan
from elsewhere: drive on a short way and scan again), :data:`UNINFORMATIVE` (the scan matched but
does not pin the pose down here, e.g. along a straight corridor: a scan from the same spot will not
either, scan where the map has features; the region is not widened) or :data:`REJECTED` (no match
inside the region or outside the gate: the next region is wider, scanning again at once is useful).
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from parcover_env.config import Scenario
from parcover_env.geometry import wrap_angle
from parcover_env.geometry.poses import compose, inverse
from parcover_env.localization.estimator import FixRequest
from parcover_env.localization.sonar.config import sonar_localizer_config
from parcover_env.localization.sonar.known_map import known_map_features
from parcover_env.localization.sonar.localizer import Ellipse, localize, scan_error
from parcover_env.localization.sonar.pin_down import shift_increase, shifted_errors
from parcover_env.localization.sonar.teammates import teammate_mask
from parcover_env.sensors.sonar import SonarRing, simulate_beams
from parcover_env.world.map_model import MapModel

__all__ = ["ACCEPTED", "HELD", "REJECTED", "UNINFORMATIVE", "SonarFixes", "scan_steps", "scan_turn"]

ACCEPTED, HELD, UNINFORMATIVE, REJECTED = 1.0, 0.5, -0.5, -1.0
"""Outcomes of a scan (``scan_result`` observation entry, ``info[agent]["sonar_fix"]``; 0 = none): fix
applied; fix held for a confirming scan from elsewhere (``confirm_widened``); matched but not pinned
down (``shift_test``); rejected. Only :data:`ACCEPTED` changes the estimate; ``< 0``: the scan found no
usable fix (as before the two middle values existed: a policy's ``< 0`` test reads both as a miss)."""


def scan_turn(beam_angles: np.ndarray) -> float:
    """How far (rad) a ring of transducers at ``beam_angles`` (robot frame, rad) turns in place until
    every direction of a 360-degree scan has been read by one of them: the largest angle between
    neighbouring transducers (72 degrees for the AmigoBot's eight; 2 pi for one transducer)."""
    a = np.sort(np.mod(np.asarray(beam_angles, dtype=float), 2 * math.pi))
    return float(np.max(np.diff(np.append(a, a[0] + 2 * math.pi))))


def scan_steps(scenario: Scenario) -> int:
    """Control steps one scan holds a robot still: ``ceil(turn / turn_rate / control_dt)`` with
    ``turn`` the ring's :func:`scan_turn` and the turn rate capped at ``robot.max_turn_rate``."""
    rate = min(scenario.observation.scan.turn_rate, scenario.robot.max_turn_rate)
    turn = scan_turn(SonarRing(scenario.robot.sonar).beam_angles)
    return max(1, math.ceil(turn / rate / scenario.physics.control_dt - 1e-9))


class SonarFixes:
    """Per-robot scans on request, localized on the known map
    (a :class:`~parcover_env.localization.estimator.FixSource`).

    ``segments``: the true walls the simulated sonar sees; ``n_robots``: the team size.
    :attr:`remaining` ``(N,)`` counts the steps left of each robot's scan (0 = not scanning),
    :attr:`result` ``(N,)`` holds each robot's last outcome and :attr:`outcome` ``(N,)`` this step's
    (:data:`ACCEPTED`, :data:`HELD`, :data:`UNINFORMATIVE`, :data:`REJECTED` or 0)."""

    name = "sonar"

    def __init__(self, scenario: Scenario, segments: np.ndarray, n_robots: int):
        cfg = self.cfg = scenario.observation.scan
        self.ring = SonarRing(scenario.robot.sonar)
        self.segments = segments
        self.radius = float(scenario.robot.radius)
        self.params = sonar_localizer_config(scenario)
        self.known, self.features, self.sectors = known_map_features(scenario.map, scenario.robot.sonar.range_max)
        sth = math.radians(cfg.fix_sigma_heading_deg)
        self.covariance = np.diag([cfg.fix_sigma_xy**2, cfg.fix_sigma_xy**2, sth**2])
        self.duration_steps = scan_steps(scenario)
        self.remaining = np.zeros(n_robots, dtype=np.int64)
        self.result = np.zeros(n_robots)
        self.outcome = np.zeros(n_robots)
        self.inflation = np.ones(n_robots)
        """Factor on each robot's search-region sigmas after rejected scans (``miss_inflation``); 1 after a fix."""
        self.held: list[np.ndarray | None] = [None] * n_robots
        """Each robot's fix held for confirmation (:meth:`confirmed`) as the correction ``fix o estimate^-1``
        of the estimate it was found from (carried to a later estimate ``e`` as ``correction o e``)."""
        self.held_from: list[np.ndarray | None] = [None] * n_robots
        """The estimate (3,) each robot's held fix was found from (a confirming scan must be from elsewhere)."""

    @property
    def scanning(self) -> np.ndarray:
        """``(N,)`` bool: the robots whose scan is under way."""
        return self.remaining > 0

    def reset(self, rng: np.random.Generator) -> None:
        self.remaining[:] = 0
        self.result[:] = 0.0
        self.outcome[:] = 0.0
        self.inflation[:] = 1.0
        self.held = [None] * len(self.held)
        self.held_from = [None] * len(self.held)

    def request(self, scan: np.ndarray, commands: np.ndarray) -> None:
        """Start a scan for each robot with ``scan (N,) > 0`` not scanning yet, then zero the commands
        ``(N, 2)`` of every scanning robot in place (held still)."""
        start = (np.asarray(scan) > 0) & (self.remaining == 0)
        self.remaining[start] = self.duration_steps
        commands[self.remaining > 0] = 0.0

    def fixes(self, request: FixRequest, rng: np.random.Generator) -> dict[int, np.ndarray]:
        """Advance every scan by one step; localize the scans that end now. Returns the accepted fixes."""
        self.outcome[:] = 0.0
        active = self.remaining > 0
        self.remaining[active] -= 1
        out = {}
        c = self.cfg
        for i in np.flatnonzero(active & (self.remaining == 0)).tolist():
            pose, informative = self.localize_scan(i, request, rng)
            if pose is None:
                outcome = REJECTED if informative else UNINFORMATIVE
            else:
                outcome = ACCEPTED if self.confirmed(i, pose, request) else HELD
            self.outcome[i] = self.result[i] = outcome
            if outcome == ACCEPTED:
                self.inflation[i] = 1.0
                self.held[i] = self.held_from[i] = None
                out[i] = pose
            elif outcome == REJECTED:  # no match inside the region: the robot may lie outside it
                self.inflation[i] = min(self.inflation[i] * c.miss_inflation, c.max_inflation)
            # held: the region stays as wide for the confirming scan; uninformative: says nothing of it
        return out

    def confirmed(self, i: int, pose: np.ndarray, request: FixRequest) -> bool:
        """Whether robot ``i``'s fix ``pose`` (3,), found in its search region, may be applied now.

        A fix inside the base gate (that of the estimate's own covariance, no ``miss_inflation``) is
        applied at once. One found only in a region widened by rejected scans is held (``confirm_widened``):
        it is applied when a later scan, taken with the estimate at least ``shift_test`` from where it was
        at the held scan, finds a fix that agrees with it, i.e. lies inside the base gate (:meth:`gate`)
        of a fresh fix's covariance (:attr:`covariance`) around the held fix carried along by the
        estimate's motion since its scan. A disagreeing fix from elsewhere replaces the held one; a fix
        from closer than ``shift_test`` (the same scene: a look-alike repeats) leaves it as it is."""
        prior = request.estimate[i]
        cov = request.covariance[i] if request.covariance is not None else np.zeros((3, 3))
        if not self.cfg.confirm_widened or self.in_gate(pose, prior, cov):
            return True
        held, held_from = self.held[i], self.held_from[i]
        if held is not None and held_from is not None and np.hypot(*(prior[:2] - held_from[:2])) < self.cfg.shift_test:
            return False
        if held is not None and self.in_gate(pose, compose(held, prior), self.covariance):
            return True
        self.held[i], self.held_from[i] = compose(pose, inverse(prior)), prior.copy()
        return False

    def in_gate(self, pose: np.ndarray, prior: np.ndarray, cov: np.ndarray) -> bool:
        """Whether ``pose`` (3,) lies inside the gate (:meth:`gate`) of an estimate ``prior`` (3,) of
        covariance ``cov (3, 3)``: Mahalanobis distance and heading."""
        pos, turn = self.gate(cov)
        d = pose[:2] - prior[:2]
        inside = float(d @ np.linalg.solve(pos, d)) <= self.cfg.gate_sigmas**2
        return inside and abs(wrap_angle(pose[2] - prior[2])) <= turn

    def localize_scan(self, i: int, request: FixRequest,
                      rng: np.random.Generator) -> tuple[np.ndarray | None, bool]:
        """Robot ``i``'s simulated scan localized in the region of its estimate and covariance: the
        accepted pose (3,) or None, and whether the scan was informative (False: the localizer's pose
        matched but the scan does not pin it down, :meth:`pins_down`; such a miss says nothing about
        the region, which is then not widened). With ``confirm_widened``, a pose found in a widened
        region outside the gate of the estimate's own covariance gives way to a match inside that gate,
        if the scan has one (:meth:`match` with no widening): the scan agrees with the estimate, and the
        far match is a look-alike of the place (generated:154, a corridor: a look-alike 1.2 m along it
        was held from the right estimate, then confirmed 0.55 m on down the same corridor)."""
        others = np.delete(np.arange(len(request.true)), i)
        ranges = self.ring.scan(request.true[i], self.segments, request.true[others, :2], self.radius, rng)
        pose, informative = self.match(i, ranges, request, float(self.inflation[i]))
        if pose is None or not self.cfg.confirm_widened or self.inflation[i] <= 1:
            return pose, informative
        cov = request.covariance[i] if request.covariance is not None else np.zeros((3, 3))
        if self.in_gate(pose, request.estimate[i], cov):
            return pose, informative
        near, _ = self.match(i, ranges, request, 1.0)
        return (pose if near is None else near), informative

    def match(self, i: int, ranges: np.ndarray, request: FixRequest,
              inflation: float) -> tuple[np.ndarray | None, bool]:
        """Robot ``i``'s scan ``ranges`` localized in the region of its estimate and covariance, the
        sigmas times ``inflation``: as :meth:`localize_scan` returns."""
        others = np.delete(np.arange(len(request.true)), i)
        prior = request.estimate[i]
        cov = request.covariance[i] if request.covariance is not None else np.zeros((3, 3))
        pos, turn = self.gate(cov * inflation**2)
        region = Ellipse.from_covariance(prior[:2], pos, self.cfg.gate_sigmas)
        res = localize(ranges, self.ring.scan_angles, self.team_map(request.estimate[others, :2]), self.sectors,
                       region, self.params, sonar=self.ring.cfg, features=self.features,
                       heading=float(prior[2]), heading_tol=turn)
        if res.pose is None or not (res.success or self.matches_unmasked(res.pose, ranges, request, others)):
            return None, True
        if not self.pins_down(res.pose, ranges, request.estimate[others, :2]):
            return None, False
        return (res.pose.copy() if self.in_gate(res.pose, prior, cov * inflation**2) else None), True

    def matches_unmasked(self, pose: np.ndarray, ranges: np.ndarray, request: FixRequest,
                         others: np.ndarray) -> bool:
        """Whether ``ranges`` match the known map's synthetic scan from ``pose`` (mean clipped error
        below ``success_error``) on the readings no teammate can explain
        (:func:`~parcover_env.localization.sonar.teammates.teammate_mask`, ``mask_sigmas``), with at
        least ``min_unmasked_share`` of the readings left."""
        if len(others) == 0:
            return False
        cov = request.covariance[others] if request.covariance is not None else np.zeros((len(others), 3, 3))
        sigma = np.sqrt(np.maximum(np.linalg.eigvalsh(cov[:, :2, :2])[:, 1], 0.0))
        reach = self.radius + self.cfg.mask_sigmas * sigma
        angles = self.ring.scan_angles
        synth = simulate_beams(self.ring.cfg, pose[None, :2], (pose[2] + angles)[None, :], self.known.segments,
                               np.zeros((0, 2)), 0.0, np.array([-1]))[0]
        keep = ~teammate_mask(pose, angles, ranges, synth, request.estimate[others, :2], reach)
        if keep.mean() < self.cfg.min_unmasked_share:
            return False
        p = self.params
        return float(scan_error(ranges[keep], synth[keep], p.error_clip, p.error_trim)[0]) <= p.success_error

    def pins_down(self, pose: np.ndarray, ranges: np.ndarray, others: np.ndarray) -> bool:
        """Whether ``ranges`` pin ``pose`` down on the known map, the teammates ``others (M, 2)`` drawn
        in at their estimates (``shift_test``, ``min_shift_increase``; always with ``shift_test`` 0)."""
        c = self.cfg
        if c.shift_test <= 0:
            return True
        errors = shifted_errors(ranges, self.ring.scan_angles, pose, segments=self.known.segments,
                                sonar=self.ring.cfg, others=others, radius=self.radius,
                                clip=self.params.error_clip, step=c.shift_test, trim=self.params.error_trim)
        return shift_increase(errors) >= c.min_shift_increase

    def gate(self, cov: np.ndarray) -> tuple[np.ndarray, float]:
        """The region of a fix for an estimate of covariance ``cov (3, 3)``: the widened position
        covariance (m^2) whose ``gate_sigmas`` ellipse the localizer searches, and the heading gate (rad,
        at most ``gate_heading_max_deg``)."""
        c = self.cfg
        pos = np.asarray(cov, dtype=float)[:2, :2] + (c.gate_distance / c.gate_sigmas) ** 2 * np.eye(2)
        turn = math.radians(c.gate_heading_deg) + c.gate_sigmas * math.sqrt(max(float(cov[2, 2]), 0.0))
        return pos, min(turn, math.radians(c.gate_heading_max_deg))

    def team_map(self, others: np.ndarray) -> MapModel:
        """The known map with the teammates as discs at their estimated positions ``others (M, 2)``."""
        if len(others) == 0:
            return self.known
        discs = shapely.union_all([shapely.Point(*q).buffer(self.radius, quad_segs=4) for q in others])
        free = self.known.free.difference(discs)
        return self.known if free.is_empty else MapModel(free=free, bounds=self.known.bounds)
