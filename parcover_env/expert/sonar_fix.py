"""Sonar fixes for robots out of Kinect view (``localization: both``).

A leader whose last absolute fix is older than ``stale_after`` stops and turns in place while its
sonar ring sweeps the 5-degree bins of a 360-degree scan (Kim, Pearce & Amato: rotate and scan), then localizes
with the relaxed-sector feature localizer on the known map. A fix becomes a correction on top of
the robot's odometry pose: ``belief = fix o odom_at_scan^-1 o odom``. A new Kinect fix (the env's
estimate becomes absolute again) clears the correction.

Uncertainty region (Kim, Pearce & Amato Sections 3-4). Until a sonar fix, the belief is the env's estimate and
its uncertainty is the pose covariance the env observes (``sigma_*`` entries, Chong & Kleeman
propagation of the odometry). After a sonar fix the expert propagates the belief's covariance
itself, from the fix's covariance and the odometry increments, with the same Jacobians
(:func:`belief_covariance_step`). The localizer searches the ``gate_sigmas`` ellipse of that
covariance (widened by ``gate_distance``), and a fix is accepted only inside it (Mahalanobis
distance) and within a heading gate grown by the heading sigma: a drifted robot's fix may lie far
off along the ellipse's major axis, while a false match along the minor axis is refused. The
covariance does not see contacts that push a robot; a successful fix refused by the gate is
therefore accepted when the next scan, from elsewhere, agrees with it (:meth:`SonarFixer.confirms`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from parcover_env.config import OdometryConfig
from parcover_env.expert.config import SonarFixConfig, expert_config
from parcover_env.geometry import wrap_angle
from parcover_env.geometry.poses import compose, inverse
from parcover_env.localization.sonar.config import sonar_localizer_config
from parcover_env.localization.sonar.scan import ScanCollector
from parcover_env.localization.sonar.service import HELD, UNINFORMATIVE
from parcover_env.sensors.odometry import propagate_covariance, wheel_increment_cov

ENV_SCAN = "env"
""":attr:`_State.scan` while the env's sonar localization service scans for this robot."""
SCAN_REQUEST = (0.0, 0.0, 1.0)
"""What :meth:`SonarFixer.step` returns to ask the env for a scan (``(v, w, scan)``)."""

__all__ = ["ENV_SCAN", "SCAN_REQUEST", "SonarFixer", "belief_covariance_step", "chain_pose", "covariance_from_entries",
           "fix_gate", "fuse_pose"]


def covariance_from_entries(entries: np.ndarray, heading: float) -> np.ndarray:
    """Invert the observation's uncertainty entries (``sigma_major, sigma_minor, sigma_axis_cos2,
    sigma_axis_sin2, sigma_heading``; axis angle in the robot frame) into a ``(3, 3)`` pose
    covariance in the world frame (m^2, rad^2). The position-heading cross terms are not observed
    and are returned as 0."""
    major, minor, c2, s2, sh = (float(v) for v in entries)
    ang = 0.5 * math.atan2(s2, c2) + heading
    c, s = math.cos(ang), math.sin(ang)
    rot = np.array([[c, -s], [s, c]])
    cov = np.zeros((3, 3))
    cov[:2, :2] = rot @ np.diag([major**2, minor**2]) @ rot.T
    cov[2, 2] = sh**2
    return cov


def belief_covariance_step(cov: np.ndarray, prev_odom: np.ndarray, odom: np.ndarray, belief_heading,
                           odometry: OdometryConfig, wheel_base: float) -> np.ndarray:
    """One step of beliefs' covariances ``(N, 3, 3)`` (or one ``(3, 3)``) from the odometry increments
    ``prev_odom -> odom`` (``(N, 3)`` poses in the odometry frame), the belief headings before the step
    (rad) and the robot's odometry model: Chong & Kleeman's propagation with the env's per-wheel
    variance (``covariance_wheel_variance`` x |wheel distance|, ``wheels`` model) or its relative
    per-step noise (``motion`` model)."""
    single = np.ndim(cov) == 2
    cov = np.asarray(cov, dtype=float)[None] if single else np.asarray(cov, dtype=float)
    prev, new = np.atleast_2d(prev_odom), np.atleast_2d(odom)
    d = new[:, :2] - prev[:, :2]
    dth = wrap_angle(new[:, 2] - prev[:, 2])
    mid = prev[:, 2] + 0.5 * dth
    ds = d[:, 0] * np.cos(mid) + d[:, 1] * np.sin(mid)
    if odometry.model == "wheels":
        half, v = 0.5 * dth * wheel_base, odometry.covariance_wheel_variance
        q = wheel_increment_cov(v * np.abs(ds - half), v * np.abs(ds + half), wheel_base)
    else:
        q = np.zeros((len(ds), 2, 2))
        q[:, 0, 0], q[:, 1, 1] = (odometry.noise_v * ds) ** 2, (odometry.noise_omega * dth) ** 2
    heading = np.broadcast_to(np.asarray(belief_heading, dtype=float), ds.shape)
    out = propagate_covariance(cov, heading, ds, dth, q)
    return out[0] if single else out


def fix_gate(cfg: SonarFixConfig, cov: np.ndarray) -> tuple[np.ndarray, float]:
    """The gate of a fix for a belief of covariance ``cov`` (3, 3): the position covariance whose
    ``gate_sigmas`` ellipse bounds the fix (m^2; ``cov`` widened by ``gate_distance`` in every
    direction), and the heading gate (rad)."""
    pos = np.asarray(cov, dtype=float)[:2, :2] + (cfg.gate_distance / cfg.gate_sigmas) ** 2 * np.eye(2)
    sigma_heading = math.sqrt(max(float(cov[2, 2]), 0.0))
    turn = min(math.radians(cfg.gate_heading_deg) + cfg.gate_sigmas * sigma_heading,
               math.radians(cfg.gate_heading_max_deg))
    return pos, turn


def chain_pose(ahead: np.ndarray, ahead_cov: np.ndarray, rel: np.ndarray, range_noise: float,
               bearing_noise: float, heading_noise: float) -> tuple[np.ndarray, np.ndarray]:
    """A follower's pose (x, y, theta) and its covariance (3, 3) from the robot ahead's pose ``ahead``
    (covariance ``ahead_cov``) and the follower camera's measurement ``rel`` of that robot in the
    follower's frame (dx, dy, relative heading): ``ahead o rel^-1``. The camera's noise (range sigma
    per metre, bearing and heading sigmas in rad, as in ``formation.camera_*_noise``) adds an
    isotropic position variance ``d^2 (range^2 + bearing^2 + heading^2)`` (a heading error turns
    the offset of length ``d``) and the heading variance; the ahead robot's heading variance turns
    the offset too (first-order Jacobian)."""
    pose = compose(ahead, inverse(rel))
    t = inverse(rel)[:2]
    c, s = math.cos(ahead[2]), math.sin(ahead[2])
    jac = np.eye(3)
    jac[0, 2], jac[1, 2] = -s * t[0] - c * t[1], c * t[0] - s * t[1]
    d2 = float(rel[0] ** 2 + rel[1] ** 2)
    noise = np.diag([d2 * (range_noise**2 + bearing_noise**2 + heading_noise**2)] * 2 + [heading_noise**2])
    return pose, jac @ np.asarray(ahead_cov, dtype=float) @ jac.T + noise


def fuse_pose(prior: np.ndarray, prior_cov: np.ndarray, measured: np.ndarray,
              measured_cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kalman update of a pose ``prior`` (covariance ``prior_cov``) with a direct measurement of the
    pose ``measured`` (covariance ``measured_cov``): gain ``K = P (P + R)^-1``, the heading
    innovation wrapped to (-pi, pi]. Returns (pose, covariance)."""
    p = np.asarray(prior_cov, dtype=float)
    gain = p @ np.linalg.pinv(p + np.asarray(measured_cov, dtype=float))
    innovation = np.asarray(measured, dtype=float) - np.asarray(prior, dtype=float)
    innovation[2] = wrap_angle(innovation[2])
    post = np.asarray(prior, dtype=float) + gain @ innovation
    post[2] = wrap_angle(post[2])
    cov = (np.eye(3) - gain) @ p
    return post, 0.5 * (cov + cov.T)


@dataclass
class _State:
    correction: np.ndarray
    cov: np.ndarray
    """Covariance of the belief (3, 3), propagated by the expert while a sonar fix corrects it."""
    last_odom: np.ndarray | None = None
    scan: ScanCollector | str | None = None
    """The scan being collected, :data:`ENV_SCAN` while the env scans, or None."""
    scan_odom: np.ndarray | None = None
    scan_cov: np.ndarray | None = None
    driven_since_scan: float = math.inf
    refused: np.ndarray | None = None
    """The correction a refused (outside the gate) but successful fix would have made, or None."""
    retries: int = 0
    """Scans in a row started at once after a refused fix (``refused_rescans``)."""
    missed: bool = False
    """The last scan gave no accepted fix."""
    env_fixed: bool = False
    """The fresh fix of these steps is the env's fix of this robot's scan (:attr:`SonarFixer.env_scan`)."""
    inflation: float = 1.0
    """Factor on the standard deviations of the gate after scans in a row without an accepted fix
    (``miss_inflation``); 1 after a fix."""
    relocate: bool = False
    """The env's last scan was held or uninformative: the next scan is taken elsewhere (``relocate_distance``)."""
    move: float | None = None
    """While relocating: the distance (m) to drive since that scan before the next one; None until the
    expert has chosen the place (:meth:`SonarFixer.scan_after`)."""
    held: bool = False
    """The env's last scan of this robot held its fix for a confirming scan from elsewhere."""
    uninformative: int = 0
    """The env's scans of this robot in a row, up to the last one, that were uninformative."""
    spaced: bool = False
    """After a second uninformative scan in a row: until a fix, the expert scans ``rescan_distance``
    apart instead of at the places the known map predicts informative (:meth:`SonarFixer.spaced`)."""


class SonarFixer:
    """Per-robot sonar localization on demand, for the scripted expert's stale leaders."""

    def __init__(self, scenario, beam_angles: np.ndarray, control_dt: float, config: SonarFixConfig | None = None,
                 env_scan: bool = False):
        from parcover_env.expert.team_localizer import TeamLocalizer

        expert = expert_config(scenario)
        self.cfg = cfg = config if config is not None else expert.sonar_fix
        self.sonar = scenario.robot.sonar
        self.odometry = scenario.robot.odometry
        self.wheel_base = scenario.robot.drive.wheel_base
        sxy, sth = scenario.observation.fix_sigma_xy, math.radians(scenario.observation.fix_sigma_heading_deg)
        self.kinect_cov = np.diag([sxy**2, sxy**2, sth**2])
        self.fix_cov = np.diag([cfg.fix_sigma**2, cfg.fix_sigma**2, math.radians(cfg.fix_sigma_heading_deg) ** 2])
        self.params = sonar_localizer_config(scenario)
        self.team = TeamLocalizer(scenario, expert.navigator, self.params)
        self.map, self.features, self.sectors = self.team.map, self.team.features, self.team.sectors
        self.beams = np.asarray(beam_angles, dtype=float)
        self.n_bins = int(round(360.0 / self.sonar.scan_step_deg))
        self.dt = control_dt
        self.scan_rate = min(cfg.scan_rate, scenario.robot.max_turn_rate)
        self.env_scan = bool(env_scan)
        """Scan through the env's sonar localization service (``observation.scan``): ask with
        :data:`SCAN_REQUEST`, hold still while the ``scanning`` entry is 1, and take the env's fix (its
        estimate, fresh ``fix_age``) instead of localizing a scan of its own."""
        self.states: dict[str, _State] = {}
        self.stats = {"sonar_scans": 0, "sonar_localized": 0, "sonar_failed": 0}

    def corrected(self, agent: str) -> bool:
        """Whether a sonar fix currently corrects this robot's odometry."""
        st = self.states.get(agent)
        return st is not None and bool(np.any(st.correction != 0.0))

    def scanning(self, agent: str) -> bool:
        """Whether this robot's scan is under way (its own, or the env's on its request)."""
        st = self.states.get(agent)
        return st is not None and st.scan is not None

    def belief(self, agent: str, odom: np.ndarray) -> np.ndarray:
        st = self.states.get(agent)
        return odom if st is None else compose(st.correction, odom)

    def covariance(self, agent: str) -> np.ndarray:
        """The covariance (3, 3) of the robot's belief at its last step (m^2, rad^2)."""
        st = self.states.get(agent)
        return np.zeros((3, 3)) if st is None else st.cov.copy()

    def step(self, agent: str, odom: np.ndarray, fix_age: float, speed: float, ranges: np.ndarray,
             is_leader: bool, at_end: bool = False, odom_cov: np.ndarray | None = None,
             others: np.ndarray | None = None, scanning: bool = False,
             check: bool = False, result: float = 0.0) -> tuple[float, ...] | None:
        """Advance this robot's scan logic; returns a (v, w) command while it is scanning. Only a robot
        that navigates by itself (``is_leader``: a leader, or a follower gone alone) starts a scan. ``at_end``:
        the robot believes it is at its route's end, where it checks its pose with a scan sooner
        (``final_rescan_distance``), since nothing later would catch a drifted arrival. ``odom_cov``:
        the observed covariance (3, 3) of the odometry pose, if the observation has one; otherwise
        the expert propagates it from the odometry increments. ``others`` ``(M, 2)``: the teammates'
        positions as the expert believes them, drawn into the map when a scan is localized.
        ``scanning``: the observation's ``scanning`` entry (:attr:`env_scan` only). ``check``: the
        robot is about to reach a KPOI (``kpoi_check_distance``): a stale leader scans now, whatever
        it drove since its last scan. ``result``: the observation's ``scan_result`` (:attr:`env_scan`
        only): after a held or uninformative scan (``relocate_distance`` > 0) the robot does not scan
        again where it stands but once it has driven the distance the expert chose
        (:meth:`needs_place`, :meth:`scan_after`)."""
        st = self.states.setdefault(agent, _State(np.zeros(3), np.zeros((3, 3))))
        fresh = fix_age < 2 * self.dt  # a fresh Kinect (or env sonar) fix: the odometry pose is absolute again
        if fresh and st.scan == ENV_SCAN and not scanning:  # the env's fix of our scan
            self.stats["sonar_localized"] += 1
            st.env_fixed = True
        if fresh:
            # after a Kinect fix a stale robot may scan at once; after its own scan's fix it drives
            # ``rescan_distance`` first, as after a fix of its own
            driven = 0.0 if st.env_fixed else math.inf
            st.correction, st.scan, st.driven_since_scan, st.refused = np.zeros(3), None, driven, None
            st.missed, st.inflation, st.relocate, st.move = False, 1.0, False, None
            st.held, st.uninformative, st.spaced = False, 0, False
            st.cov = self.kinect_cov.copy() if odom_cov is None else odom_cov
        elif odom_cov is not None and not self.corrected(agent):
            st.cov = odom_cov
        elif st.last_odom is not None:
            heading = float(self.belief(agent, st.last_odom)[2])
            st.cov = belief_covariance_step(st.cov, st.last_odom, odom, heading, self.odometry, self.wheel_base)
        st.last_odom = odom.copy()
        if not fresh:
            st.env_fixed = False
        if fresh:
            return None
        st.driven_since_scan += abs(speed) * self.dt
        if st.scan is None:
            rescan = self.cfg.final_rescan_distance if at_end else self.cfg.rescan_distance
            # with the env's scans a miss widens the env's next search region: scan again at once
            missed = st.missed and (at_end or self.env_scan)
            retry = (st.refused is not None or missed) and st.retries < self.cfg.refused_rescans
            due = retry or check or st.driven_since_scan >= rescan
            if st.relocate:  # scan again only where the expert chose (never where it stands)
                retry, due = False, check or (st.move is not None and st.driven_since_scan >= st.move)
            if not (is_leader and fix_age > self.cfg.stale_after and due):
                return None
            if abs(speed) > self.cfg.stop_speed:
                return 0.0, 0.0  # brake first: a scan is taken standing still
            st.retries = st.retries + 1 if retry else 0
            if self.env_scan:
                st.scan = ENV_SCAN
                self.stats["sonar_scans"] += 1
                return SCAN_REQUEST
            st.scan = ScanCollector(self.beams, self.n_bins, self.sonar.range_max, float(odom[2]))
            st.scan_odom, st.scan_cov = odom.copy(), st.cov * st.inflation**2
            self.stats["sonar_scans"] += 1
        if st.scan == ENV_SCAN:
            if scanning:
                return 0.0, 0.0
            # the env's scan ended without a fix (a fix is fresh above): search wider next time, or,
            # after a held or uninformative scan, scan next from elsewhere
            st.scan, st.driven_since_scan = None, 0.0
            elsewhere = self.cfg.relocate_distance > 0 and result in (HELD, UNINFORMATIVE)
            st.missed, st.relocate, st.move = not elsewhere, elsewhere, None
            st.held = elsewhere and result == HELD
            st.uninformative = st.uninformative + 1 if result == UNINFORMATIVE else 0
            st.spaced = st.spaced or (elsewhere and st.uninformative >= 2)
            self.stats["sonar_failed"] += 1
            return None
        if not st.scan.add(float(odom[2]), ranges):
            return 0.0, self.scan_rate
        self._localize(st, np.zeros((0, 2)) if others is None else np.asarray(others, dtype=float))
        st.scan, st.driven_since_scan = None, 0.0
        return None

    def needs_place(self, agent: str) -> bool:
        """Whether this robot's last env scan was held or uninformative and the expert has not yet
        chosen where it scans next (:meth:`scan_after`)."""
        st = self.states.get(agent)
        return st is not None and st.relocate and st.move is None

    def waiting_distance(self, agent: str) -> float | None:
        """The distance (m) a relocating robot drives since its last scan before the next one, as the
        expert chose it (:meth:`scan_after`); None if it is not relocating or nothing is chosen yet."""
        st = self.states.get(agent)
        return st.move if st is not None and st.relocate else None

    def choose_again(self, agent: str) -> None:
        """Forget where a relocating robot was to scan next (:meth:`needs_place` is True again)."""
        st = self.states.get(agent)
        if st is not None and st.relocate:
            st.move = None

    def relocating(self, agent: str) -> bool:
        """Whether this robot waits to scan from elsewhere (after a held or uninformative scan)."""
        st = self.states.get(agent)
        return st is not None and st.relocate

    def held(self, agent: str) -> bool:
        """Whether this robot relocates after a scan whose fix the env holds for a confirming scan from
        elsewhere (``scan_result`` 0.5)."""
        st = self.states.get(agent)
        return st is not None and st.relocate and st.held

    def spaced(self, agent: str) -> bool:
        """Whether, since this robot's last fix, two of its env scans in a row were uninformative (the
        second one at a place the expert chose, ``relocate_distance``): until a fix it scans
        ``rescan_distance`` apart, the known map's prediction having failed here."""
        st = self.states.get(agent)
        return st is not None and st.spaced

    def scan_after(self, agent: str, distance: float) -> None:
        """A relocating robot scans next once it has driven ``distance`` (m) since its last scan
        (``math.inf``: not before a fix from elsewhere; 0: now)."""
        st = self.states[agent]
        st.move = float(distance)

    def relative_update(self, agent: str, odom: np.ndarray, measured: np.ndarray, measured_cov: np.ndarray) -> None:
        """Fuse a pose measured relative to a teammate (:func:`chain_pose`) into this robot's belief;
        call after :meth:`step` of this step. A correction from it counts like a fix."""
        st = self.states.setdefault(agent, _State(np.zeros(3), np.zeros((3, 3))))
        pose, st.cov = fuse_pose(self.belief(agent, odom), st.cov, measured, measured_cov)
        st.correction = compose(pose, inverse(odom))

    def accept(self, fix: np.ndarray, prior: np.ndarray, cov: np.ndarray) -> bool:
        """Whether the sonar ``fix`` (x, y, theta) is believable as a correction of ``prior`` whose
        covariance is ``cov`` (3, 3): inside the gate ellipse and within the heading gate."""
        pos, turn = fix_gate(self.cfg, cov)
        d = np.asarray(fix[:2], dtype=float) - np.asarray(prior[:2], dtype=float)
        inside = float(d @ np.linalg.solve(pos, d)) <= self.cfg.gate_sigmas**2
        return bool(inside and abs(wrap_angle(fix[2] - prior[2])) <= turn)

    def _localize(self, st: _State, others: np.ndarray) -> None:
        from parcover_env.localization.sonar import Ellipse

        prior = compose(st.correction, st.scan_odom)
        pos, turn = fix_gate(self.cfg, st.scan_cov)
        ell = Ellipse.from_covariance(prior[:2], pos, self.cfg.gate_sigmas)
        fix = self.team.localize(st.scan.ranges, ell, others, heading=float(prior[2]), heading_tol=turn)
        pose = fix.result.pose
        usable = fix.ok and self.pins_down(st.scan.ranges, pose, others)
        if usable and (self.accept(pose, prior, st.scan_cov) or self.confirms(pose, st.refused, st.scan_odom)):
            st.correction = compose(pose, inverse(st.scan_odom))
            st.cov, st.refused = self.fix_cov.copy(), None
            st.missed, st.inflation = False, 1.0
            self.stats["sonar_localized"] += 1
            return
        if usable and abs(wrap_angle(pose[2] - prior[2])) <= math.radians(self.cfg.gate_heading_max_deg):
            st.refused = compose(pose, inverse(st.scan_odom))
        # no fix: the belief may be further off than its covariance says (contacts push robots unseen
        # by the encoders), so the next scan searches a wider region
        st.missed = True
        st.inflation = min(st.inflation * self.cfg.miss_inflation, self.cfg.max_inflation)
        self.stats["sonar_failed"] += 1

    def pins_down(self, ranges: np.ndarray, pose: np.ndarray, others: np.ndarray) -> bool:
        """Whether the binned scan ``ranges`` pins ``pose`` down (``shift_test``, ``min_shift_increase``)."""
        from parcover_env.expert.team_localizer import shift_sensitivity

        if self.cfg.shift_test <= 0:
            return True
        errors = self.team.shifted_errors(ranges, pose, others, self.cfg.shift_test)
        return shift_sensitivity(errors) >= self.cfg.min_shift_increase

    def confirms(self, fix: np.ndarray, refused: np.ndarray | None, odom: np.ndarray) -> bool:
        """Whether ``fix`` agrees with an earlier refused fix carried to here by the odometry
        (``refused o odom``) within ``confirm_distance`` and ``gate_heading_deg``: two scans from
        different places agreeing on the same correction outweigh an overconfident covariance (pushes
        and slip the odometry cannot see)."""
        if refused is None:
            return False
        carried = compose(refused, odom)
        return bool(np.hypot(*(fix[:2] - carried[:2])) <= self.cfg.confirm_distance
                    and abs(wrap_angle(fix[2] - carried[2])) <= math.radians(self.cfg.gate_heading_deg))
