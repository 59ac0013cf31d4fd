"""ScriptedExpert: Min et al.'s robots, end to end — leaders drive the plan, followers keep formation.

The expert acts from the agents' observations plus what the paper's Kinect system knows, passed
explicitly: the scenario (map, robot model, formation parameters) and the PPCP plan. It never reads
env internals. Roles (leader/follower), splits at TPs, and waypoints come from the observations
(the env runs the Kinect system's Alg. 1); each robot then runs its own controller:

* leader: go-to-goal toward its next waypoint (our law on eq. 2's unicycle kinematics), slowed to
  ``expert.leader_speed`` of v_max while it has followers so they can close gaps;
* follower: Das et al.'s l-psi law (in place of the garbled eq. 3) on its onboard camera's
  measurement of the robot ahead, the leader's velocity estimated from successive measurements
  (limited information, ref. [8]);
  if the robot ahead is out of sight, it drives along its own route (same path up to its split);
* with ``localization: both``, or with the env's sonar localization service (``observation.scan``,
  how ``parcover run --policy expert`` builds the env) on a map without Kinects, a leader out of
  Kinect view for a while stops and scans (the env's service: it asks with the ``scan`` action and
  reads the env's estimate and covariance; without the service it turns and localizes its own scan
  with Kim, Pearce & Amato's localizer, :mod:`parcover_env.expert.sonar_fix`), and checks its pose
  by a scan before each KPOI and at its route's end; with ``expert.sonar_fix.relocate_distance`` > 0
  (0.5 m by default; the registered expert's env holds fixes found only in a widened region), after
  a scan whose fix the env holds for confirmation or that was uninformative
  (``scan_result`` 0.5 / -0.5) it scans next from elsewhere, where the known map predicts an
  informative scan (:mod:`parcover_env.expert.scan_places`; after two uninformative scans in a row,
  ``rescan_distance`` apart), and a robot stuck meanwhile drives into the freest direction of its
  sonar ring first (``stuck_time``);
* leaders brake on their front sonar beams when a robot or wall is closer than ``stop_margin``
  (needed in ``individual`` mode, where all robots leave at once); a leader braked for longer than
  ``patience`` (plus ``patience_stagger`` per robot index, so two robots never give way together)
  backs off briefly while turning, which breaks face-to-face deadlocks.

Every tunable is a field of the scenario's ``expert`` section (:class:`~parcover_env.expert.config.ExpertConfig`).
"""

from __future__ import annotations

import numpy as np

from parcover_env.control.follower import LeaderVelocityEstimator, l_psi_control, relative_l_psi
from parcover_env.control.leader import go_to_goal
from parcover_env.envs.observations import ObservationLayout
from parcover_env.expert.avoidance import brake_factor
from parcover_env.expert.config import ExpertConfig, expert_config
from parcover_env.expert.odometry_drift import DriftCalibration
from parcover_env.expert.sonar_fix import SCAN_REQUEST, chain_pose, covariance_from_entries
from parcover_env.geometry import atan2, rotate, segments_blocked, wrap_angle
from parcover_env.geometry.poses import compose, inverse
from parcover_env.geometry.rays import point_segment_distance
from parcover_env.planning.free_space import DiscPaths
from parcover_env.policies.protocol import Policy
from parcover_env.scenarios import Mission, RouteTracker

__all__ = ["ScriptedExpert"]


class ScriptedExpert(Policy):
    """Min et al.'s robots as a policy: ``for_env(env)``, ``reset(obs)``, ``act(obs) -> actions``, ``stats()``.

    Every tunable comes from ``config`` (default: the scenario's ``expert`` section,
    :class:`~parcover_env.expert.config.ExpertConfig`).
    """

    def __init__(self, layout: ObservationLayout, mission: Mission, sonar_angles: np.ndarray | None = None,
                 config: ExpertConfig | None = None):
        self.layout, self.mission = layout, mission
        self.scenario = scenario = mission.scenario
        self.cfg = cfg = config if config is not None else expert_config(scenario)
        self.plan = mission.plan
        self.dt = control_dt = scenario.physics.control_dt
        r = scenario.robot
        self.v_max, self.w_max = r.max_speed, r.max_turn_rate
        self.sonar_front = None
        if sonar_angles is not None and len(sonar_angles):
            front = np.abs(wrap_angle(np.asarray(sonar_angles))) <= np.radians(cfg.front_sector_deg)
            self.sonar_front = np.flatnonzero(front)
        self.stop = r.radius + cfg.stop_margin
        self.slow = r.radius + cfg.slow_margin
        self.fixer = None
        env_scan = "scanning" in layout.slices
        # sonar fixes with ``localization: both``, or through the env's service wherever no Kinect
        # ever fixes a robot (the estimate is odometry alone otherwise)
        if sonar_angles is not None and (scenario.localization == "both" or (env_scan and not scenario.kinects)):
            from parcover_env.expert.sonar_fix import SonarFixer

            self.fixer = SonarFixer(scenario, sonar_angles, control_dt, cfg.sonar_fix, env_scan=env_scan)
        self.places = None
        if self.fixer is not None and env_scan:
            from parcover_env.expert.scan_places import ScanPlaces

            self.places = ScanPlaces(scenario, mission.known_map.segments)
        self.detours: dict[str, np.ndarray] = {}
        """Where a robot at its route's end drives back to scan from (after a held or uninformative scan),
        or where a stuck robot with a held fix drives to (:meth:`_escape`)."""
        self.still: dict[str, tuple[np.ndarray, int]] = {}
        """Per relocating robot: where its estimate was when it last moved ``stuck_distance``, and the
        steps since (:meth:`_stuck`)."""
        self.back: dict[str, float] = {}
        """Per robot: how far back from its route's end (m) its last detour place there lies, until a fix: a
        scan there without a fix means the known map's prediction failed, and the next one is farther back."""
        self.paths: DiscPaths | None = None
        """Shortest paths of the robot's disc grown by ``stop_margin`` through the known map (:meth:`_disc_paths`)."""
        self.escaping: set[str] = set()
        """Robots driving into the freest direction of their sonar ring before their next scan."""
        # with sonar fixes, the robots' progress along their routes is tracked on the corrected pose
        # (the env's waypoints follow its odometry estimate), from the start so that out-and-back
        # legs are never confused
        self.track: RouteTracker | None = None
        self.estimators: dict[str, LeaderVelocityEstimator] = {}
        self.blocked: dict[str, int] = {}
        self.unseen: dict[str, int] = {}  # steps since each follower last saw the robot ahead
        self.backing: dict[str, int] = {}
        self.checked: set[tuple[str, int]] = set()
        """(robot, KPOI index) pairs whose pose check before the KPOI is done (``kpoi_check_distance``)."""
        self.checking: dict[str, np.ndarray] = {}
        """Per robot whose last scan was its pose check before a KPOI and gave no fix yet: that KPOI; it
        scans from a place back along its route before going on (:meth:`_relocate`)."""
        self._last_odom = np.zeros((mission.n_robots, 3))
        """The odometry pose of each robot at the last step (calibrated with :attr:`drift` when there is one)."""
        self._raw = np.zeros((mission.n_robots, 3))
        """The observed odometry pose (the env's estimate) of each robot at the last step."""
        self.drift: DriftCalibration | None = None
        """Heading drift calibration of the robots' odometry (``expert.sonar_fix.calibrate_drift``)."""

    @classmethod
    def for_env(cls, env, **kwargs) -> ScriptedExpert:
        """Build from an env's public spec: observation layout, mission (scenario, plan), sonar beams.

        Always a ScriptedExpert; :func:`parcover_env.expert.expert_for` picks the expert that suits
        the scenario's localization mode (the stop-and-scan navigator with ``localization: sonar``).
        """
        angles = env.sonar.beam_angles if env.sonar is not None else None
        return cls(env.layout, env.mission, angles, **kwargs)

    def stats(self) -> dict:
        return dict(self.fixer.stats) if self.fixer is not None else {}

    def belief(self) -> np.ndarray:
        """``(N, 3)`` poses the robots steer by at the last step: the observed estimate, corrected by
        a sonar fix where there is one."""
        out = self._last_odom.copy()
        if self.fixer is not None:
            for i in range(len(out)):
                out[i] = self.fixer.belief(f"robot_{i}", out[i])
        return out

    def reset(self, observations=None) -> None:
        self.track = self.mission.tracker() if self.fixer is not None else None
        r = self.scenario.robot
        self.drift = (DriftCalibration(self.mission.n_robots, r.odometry, r.drive.wheel_base)
                      if self.fixer is not None and self.cfg.sonar_fix.calibrate_drift and r.odometry.model == "wheels"
                      else None)
        if self.fixer is not None:
            self.fixer.states.clear()
        self.estimators.clear()
        self.blocked.clear()
        self.backing.clear()
        self.unseen.clear()
        self.checked.clear()
        self.checking.clear()
        self.detours.clear()
        self.still.clear()
        self.back.clear()
        self.escaping.clear()

    def act(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        g = self.layout.get
        agents = sorted(observations, key=lambda a: int(a.rsplit("_", 1)[1]))
        leaders = {a: g(observations[a], "leader")[0] > 0.5 for a in agents}
        has_followers = {a: i + 1 < len(agents) and not leaders[agents[i + 1]] for i, a in enumerate(agents)}
        scans = {}
        for a in agents:
            self._read_odometry(a, observations[a])
        alone = self._alone(observations, agents, leaders)
        team = self._team_positions(observations, agents, leaders) if self.fixer is not None else None
        for a in agents:
            obs = observations[a]
            others = None if team is None else np.delete(team, int(a.rsplit("_", 1)[1]), axis=0)
            scans[a] = self._sonar_fix(a, obs, leaders[a] or alone[a], others) if self.fixer is not None else None
        bel = None
        if self.fixer is not None:
            if self.cfg.sonar_fix.follow_chain:
                self._chain_followers(observations, agents, leaders, scans)
            bel = self.belief()
            if self.track is None:
                self.track = self.mission.tracker()
            self.track.update(bel[:, :2], bel[:, :2], 0.0)
        actions = {}
        for a in agents:
            obs = observations[a]
            if scans[a] is not None:
                v, w = scans[a][:2]
            elif leaders[a]:
                self.estimators.pop(a, None)
                scale = self.cfg.leader_speed if has_followers[a] else 1.0
                v, w = go_to_goal(self._goal(obs, a, bel), self.v_max, self.w_max, speed_scale=scale)
                v, w = self._avoid(a, obs, v, w)
            elif g(obs, "pred_visible")[0] > 0.5:
                v, w = self._follow(a, obs)
            else:
                self.estimators.pop(a, None)
                v, w = go_to_goal(self._goal(obs, a, bel), self.v_max, self.w_max, speed_scale=self.cfg.search_speed)
            actions[a] = np.array([v / self.v_max, w / self.w_max], dtype=np.float32)
        if "scanning" in self.layout.slices:  # the env's sonar localization service: (v, w, scan)
            actions = {a: np.append(act, np.float32(1.0 if scans[a] == SCAN_REQUEST else -1.0))
                       for a, act in actions.items()}
        return actions

    def _goal(self, obs: np.ndarray, agent: str, bel: np.ndarray | None) -> np.ndarray:
        """The route point in the robot frame: the observed one, or with sonar fixes the expert's own
        tracker's from its belief (the corrected pose, or the observed estimate while no correction is
        on: the env's progress follows the env's estimate, which a follower's chained belief may have
        left far behind, generated:289 and 314); see :meth:`_visible_goal` for a robot off its route."""
        i = int(agent.rsplit("_", 1)[1])
        if agent in self.detours:
            pose = self._odom(obs) if bel is None else bel[i]
            return rotate(self.detours[agent] - pose[:2], -pose[2])
        if bel is None:
            pose = self._odom(obs)
            rel = np.array([self.layout.get(obs, "goal_dx")[0], self.layout.get(obs, "goal_dy")[0]])
        else:
            # the expert's own tracker, also when no correction is on: the env's progress followed the
            # env's estimate, which as a follower's may have drifted beyond the tracker's ``max_offset``
            # (no progress) or onto a later leg, while the expert's belief was chained to the leader
            pose = bel[i]
            rel = rotate(self.track.goals()[i] - pose[:2], -pose[2])
        return self._visible_goal(i, pose, rel)

    def _visible_goal(self, i: int, pose: np.ndarray, rel: np.ndarray) -> np.ndarray:
        """``rel`` (robot frame), unless robot ``i`` is farther than ``off_route_distance`` from its
        route ahead (from its tracked progress on; the whole route without a tracker) and its body
        (radius + ``stop_margin``) cannot drive straight to that point through the known map: then
        the latest route vertex before the point that it can drive straight to (back to its route
        around the corner), else the first bend of the shortest path of its body to the point
        (:class:`~parcover_env.planning.free_space.DiscPaths`, :func:`steer_point`). Measured from the
        progress on: a robot coming back to its route from a teammate's branch may lie nearer a later
        leg than the leg it needs, and progress then jumps there (generated:201, robot 5: 0.4 m from its
        route, its goal behind a wall, braking and backing off against it to the end of the episode).
        Tested with the body, not the centre line: generated:18 and 7190 (a robot promoted in a door
        gap, its goal's line a few cm below the wall beside the door, braked and backed off there to
        the episode's end)."""
        route = self.mission.routes[i]
        if len(route) < 2:
            return rel
        xy = pose[:2]
        ahead = route if self.track is None else route_from(route, float(self.track.progress[i]))
        off = float(point_segment_distance(xy[None], np.c_[ahead[:-1], ahead[1:]]).min())
        if off <= self.cfg.off_route_distance:
            return rel
        goal = xy + rotate(rel, pose[2])
        paths = self._disc_paths()
        if paths.clear(xy, goal):
            return rel
        upto = int(np.argmin(np.hypot(*(route - goal).T))) + 1
        for k in range(upto - 1, -1, -1):  # the latest route vertex it can drive straight to
            if paths.clear(xy, route[k]):
                return rotate(route[k] - xy, -pose[2])
        way = paths.path(xy, goal)
        if way is not None:
            return rotate(steer_point(way, xy, self.scenario.robot.radius) - xy, -pose[2])
        # no way for its body on the known map: by the centre line (as before 2026-11-28)
        walls = self.mission.known_map.segments
        if not segments_blocked(xy[None], goal[None], walls)[0]:
            return rel
        seen = ~segments_blocked(np.repeat(xy[None], upto, axis=0), route[:upto], walls)
        if seen.any():
            return rotate(route[int(np.flatnonzero(seen)[-1])] - xy, -pose[2])
        # none of its own route in sight (carried into a teammate's branch): back along the plan tree
        via = route_tree_waypoint(self.mission.routes, xy, route[upto - 1], walls)
        return rel if via is None else rotate(via - xy, -pose[2])

    def _disc_paths(self) -> DiscPaths:
        """Shortest paths through the known map for the robot's body and its ``stop_margin`` (built on
        first use: only a robot off its route steers by them)."""
        if self.paths is None:
            self.paths = DiscPaths(self.mission.known_map.free, self.stop)
        return self.paths

    def _read_odometry(self, agent: str, obs: np.ndarray) -> None:
        """Store the robot's observed odometry pose and the pose it steers from: calibrated for its heading
        drift (:attr:`drift`), restarted at each fresh fix (``fix_age``) and measured against it."""
        i = int(agent.rsplit("_", 1)[1])
        self._raw[i] = raw = self._odom(obs)
        if self.drift is None:
            self._last_odom[i] = raw
            return
        g = self.layout.get
        fresh = float(g(obs, "fix_age")[0]) < 2 * self.dt
        var = (float(g(obs, "sigma_heading")[0]) ** 2 if "sigma_heading" in self.layout.slices
               else float(self.fixer.fix_cov[2, 2]))
        self._last_odom[i] = self.drift.step(i, raw, fresh, var)

    def _odom(self, obs: np.ndarray) -> np.ndarray:
        g = self.layout.get
        return np.array([g(obs, "x")[0], g(obs, "y")[0], atan2(g(obs, "sin_theta")[0], g(obs, "cos_theta")[0])])

    def _ahead(self, obs: np.ndarray) -> np.ndarray:
        """The follower camera's measurement of the robot ahead, in the follower's frame: (dx, dy, heading)."""
        g = self.layout.get
        return np.array([g(obs, "pred_dx")[0], g(obs, "pred_dy")[0],
                         atan2(g(obs, "pred_sin")[0], g(obs, "pred_cos")[0])], dtype=float)

    def _team_positions(self, observations: dict, agents: list[str], leaders: dict) -> np.ndarray:
        """``(N, 2)`` where the expert believes the robots are: a follower that sees the robot ahead
        is placed by its camera measurement relative to that robot (chained along the column from the
        leader), any other robot at its belief. Scans draw the teammates into the map there."""
        g = self.layout.get
        pose = self.belief()
        for a in agents:
            i = int(a.rsplit("_", 1)[1])
            obs = observations[a]
            if i == 0 or leaders[a] or g(obs, "pred_visible")[0] <= 0.5 or f"robot_{i - 1}" not in observations:
                continue
            rel = self._ahead(obs)
            pose[i] = compose(pose[i - 1], inverse(rel))
        return pose[:, :2]

    def _alone(self, observations: dict, agents: list[str], leaders: dict) -> dict[str, bool]:
        """Which followers have not seen the robot ahead for ``alone_after`` seconds."""
        limit = self.cfg.alone_after / self.dt
        out = {}
        for a in agents:
            seen = leaders[a] or self.layout.get(observations[a], "pred_visible")[0] > 0.5
            self.unseen[a] = 0 if seen else self.unseen.get(a, 0) + 1
            out[a] = self.unseen[a] >= limit
        return out

    def _chain_followers(self, observations: dict, agents: list[str], leaders: dict, scans: dict) -> None:
        """Fuse into each follower's belief the pose its camera implies relative to the robot ahead
        (``expert.sonar_fix.follow_chain``), front to back so that each uses the updated belief ahead."""
        g, f = self.layout.get, self.scenario.formation
        for a in agents:
            i = int(a.rsplit("_", 1)[1])
            obs = observations[a]
            if (i == 0 or leaders[a] or scans[a] is not None or g(obs, "pred_visible")[0] <= 0.5
                    or f"robot_{i - 1}" not in observations):
                continue
            ahead = f"robot_{i - 1}"
            rel = self._ahead(obs)
            pose, cov = chain_pose(self.fixer.belief(ahead, self._last_odom[i - 1]), self.fixer.covariance(ahead), rel,
                                   f.camera_range_noise, f.camera_bearing_noise, f.camera_heading_noise)
            self.fixer.relative_update(a, self._last_odom[i], pose, cov)
            if self.drift is not None and self.drift.due(i):  # its chained heading measures its odometry's drift
                self.drift.measure(i, float(self._raw[i, 2]), float(pose[2]), float(cov[2, 2]))

    def _sonar_fix(self, agent: str, obs: np.ndarray, leader: bool,
                   others: np.ndarray | None = None) -> tuple[float, float] | None:
        g = self.layout.get
        i = int(agent.rsplit("_", 1)[1])
        odom = self._last_odom[i].copy()
        end = self.mission.routes[i][-1]
        at_end = bool(np.hypot(*(self.fixer.belief(agent, odom)[:2] - end)) <= self.mission.waypoint_tol)
        cov = None
        if "sigma_major" in self.layout.slices:
            names = ("sigma_major", "sigma_minor", "sigma_axis_cos2", "sigma_axis_sin2", "sigma_heading")
            cov = covariance_from_entries(np.array([g(obs, k)[0] for k in names], dtype=float), float(self._raw[i, 2]))
        scanning = "scanning" in self.layout.slices and bool(g(obs, "scanning")[0] > 0.5)
        check = self._kpoi_check(agent, obs, odom) if leader else None
        result = float(g(obs, "scan_result")[0]) if "scan_result" in self.layout.slices else 0.0
        out = self.fixer.step(agent, odom, float(g(obs, "fix_age")[0]), float(g(obs, "v")[0]),
                              g(obs, "sonar").astype(float), leader, at_end, cov, others, scanning,
                              check=check is not None, result=result)
        if check is not None and self.fixer.scanning(agent):
            self.checked.add((agent, check))
            self.checking[agent] = self.mission.kpois[check]
        self._relocate(agent, i, odom, at_end, g(obs, "sonar").astype(float))
        return out

    def _relocate(self, agent: str, i: int, odom: np.ndarray, at_end: bool, ranges: np.ndarray) -> None:
        """After a held or uninformative env scan, choose where the robot scans next
        (``expert.sonar_fix.relocate_distance``): the first place ahead along its route where the known map
        predicts an informative scan (after a second uninformative scan in a row, :meth:`SonarFixer.spaced`,
        and an uninformative last one: ``rescan_distance`` on); at its route's end, such a place back along
        it (a detour, scanned on arrival): within ``rescan_distance`` or, in open space, farther back as far as
        it sees its route (generated:198, 201, 367, 399: at a wall of an open room it stood uninformed at its
        route's end to the episode's end), beyond the last detour place whose scan gave no fix; a robot that
        reaches its route's end before the place chosen ahead chooses again there. After its pose check
        before a KPOI (``kpoi_check_distance``) gave no fix, the same place back along its route, up to that
        KPOI's route vertex, before it goes on (generated:7018; :attr:`checking`). A stuck robot
        (:meth:`_stuck`; after a held scan, or an uninformative one away from its route's end) drives into
        the freest direction of its sonar ``ranges``
        first (:meth:`_escape`). Drops the detour once the robot scans or is fixed."""
        if not self.fixer.relocating(agent):  # fixed: a place behind its route's end worked or is not needed
            self.back.pop(agent, None)
            if not self.fixer.scanning(agent):
                self.checking.pop(agent, None)
        if self.fixer.scanning(agent) or not self.fixer.relocating(agent):
            self.detours.pop(agent, None)
            self.still.pop(agent, None)
            self.escaping.discard(agent)
            return
        pose = self.fixer.belief(agent, odom)
        bel = pose[:2]
        stuck = self._stuck(agent, bel)
        # an escape may be shorter than waypoint_tol: it ends closer, so that the scan is from elsewhere
        tol = 0.5 * self.cfg.sonar_fix.stuck_distance if agent in self.escaping else self.mission.waypoint_tol
        arrived = agent in self.detours and np.hypot(*(bel - self.detours[agent])) <= tol
        if arrived or (stuck and agent in self.escaping):
            self.fixer.scan_after(agent, 0.0)  # there, or as far as it got: scan now
            return
        if stuck and (self.fixer.held(agent) or not at_end):  # at its route's end it stands still on purpose
            self._escape(agent, pose, ranges)
            return
        wait = self.fixer.waiting_distance(agent)
        if at_end and wait is not None and np.isfinite(wait) and agent not in self.detours:
            # it reached its route's end before the place chosen ahead (generated:314, robot 1, spaced
            # scans in an open room): it would stand there for good; choose as at its route's end
            self.fixer.choose_again(agent)
        if self.places is None or not self.fixer.needs_place(agent):
            return
        c = self.cfg.sonar_fix
        near, far = c.relocate_distance, max(c.relocate_distance, c.rescan_distance)
        route = self.mission.routes[i]
        progress = float(self.track.progress[i]) if self.track is not None else 0.0
        if agent in self.checking and not at_end:
            # its pose check before a KPOI gave no fix: scan from a place back along its route before the
            # KPOI, as at its route's end (generated:7018, robot 3: it went on to the KPOI on a belief
            # 0.4 m off after an uninformative check and never came nearer than 0.48 m to it)
            upto = route_upto(route, progress, self.checking[agent], self.mission.waypoint_tol)
            if upto is not None and self._detour_behind(agent, upto, bel, near, far):
                return
            self.checking.pop(agent)  # no such place: on along its route, as after any other scan
        if self.fixer.spaced(agent) and not self.fixer.held(agent) and not at_end:  # a held scan was informative
            self.fixer.scan_after(agent, c.rescan_distance)
            return
        if at_end:
            self._detour_behind(agent, route, bel, near, far)
            return
        d = self.places.ahead(route, progress, near, far)
        if d is not None and d < near:
            # the place ahead is its route's end, nearer than ``relocate_distance`` along the route while its
            # belief is not there yet: a scan after driving d would be taken where it stands (generated:7061,
            # robot 3: a held scan repeated in place six times, d = 0): as at its route's end, a place back
            # along its route, else on at least ``relocate_distance``
            if self._detour_behind(agent, route, bel, near, far):
                return
            d = near
        self.fixer.scan_after(agent, c.rescan_distance if d is None else d)

    def _detour_behind(self, agent: str, route: np.ndarray, xy: np.ndarray, near: float, far: float) -> bool:
        """Send the robot at ``xy`` (its belief) to scan at the first place back from the end of ``route``
        that the known map predicts informative and it sees: ``near`` to ``far`` metres back (beyond the last
        such place whose scan gave no fix, :attr:`back`), else farther, as far as it sees the route; it scans
        there on arrival and not before. Whether a place was found (else it waits for a fix, at its route's end)."""
        c = self.cfg.sonar_fix
        if agent in self.back:  # its scan at the last place behind gave no fix: beyond that place
            near = self.back[agent] + c.relocate_distance
            far = max(far, near)
        found = self.places.behind_at(route, xy, near, far)
        if found is None:  # none within ``far`` (open space): farther back, as far as it sees its route
            found = self.places.behind_at(route, xy, far, route_length(route))
        if found is not None:
            self.detours[agent], self.back[agent] = found
        self.fixer.scan_after(agent, np.inf)
        return found is not None

    def _stuck(self, agent: str, xy: np.ndarray) -> bool:
        """Whether a relocating robot at ``xy`` (its belief) has stayed within ``stuck_distance`` of one
        point for ``stuck_time`` (``expert.sonar_fix``); the count restarts once it reports True."""
        c = self.cfg.sonar_fix
        anchor, steps = self.still.get(agent, (xy, -1))
        if np.hypot(*(xy - anchor)) >= c.stuck_distance:
            anchor, steps = xy, -1
        steps += 1
        if steps * self.dt >= c.stuck_time - 1e-9:
            anchor, steps = xy, 0
            self.still[agent] = (anchor, steps)
            return True
        self.still[agent] = (anchor, steps)
        return False

    def _escape(self, agent: str, pose: np.ndarray, ranges: np.ndarray) -> None:
        """Send a stuck robot at ``pose`` (its belief) ``relocate_distance`` into the freest direction of its
        sonar ring ``ranges``: the beam whose front sector (the beams within ``front_sector_deg`` of it, those
        it brakes on when it drives that way) has the longest shortest reading (the first of equal ones), at
        most up to ``stop_margin`` before that reading. It scans on arrival or when stuck again (no estimate
        is needed to choose the direction)."""
        beams = np.asarray(self.fixer.beams, dtype=float)
        sector = np.abs(wrap_angle(beams[None, :] - beams[:, None])) <= np.radians(self.cfg.front_sector_deg)
        clear = np.where(sector, np.asarray(ranges, dtype=float)[None, :], np.inf).min(axis=1)
        k = int(np.argmax(clear))
        reach = min(self.cfg.sonar_fix.relocate_distance, float(clear[k]) - self.stop)
        if reach < self.cfg.sonar_fix.stuck_distance:
            return  # boxed in: wait where it is
        heading = pose[2] + float(self.fixer.beams[k])
        self.detours[agent] = pose[:2] + reach * np.array([np.cos(heading), np.sin(heading)])
        self.escaping.add(agent)
        self.fixer.scan_after(agent, np.inf)  # not before it gets there

    def _kpoi_check(self, agent: str, obs: np.ndarray, odom: np.ndarray) -> int | None:
        """The index of the KPOI at the robot's route point ahead (within ``waypoint_tol``), if the robot believes it is
        within ``kpoi_check_distance`` of it and has not checked its pose before it yet; else None."""
        reach = self.cfg.sonar_fix.kpoi_check_distance
        # a correction from the expert's own sonar fix needs no check; with the env's scans the only
        # correction is a follower's camera chain (:meth:`_chain_followers`), never checked by a scan: a
        # promoted follower reached its first KPOI on it unchecked
        if reach <= 0 or (self.fixer.corrected(agent) and not self.fixer.env_scan):
            return None
        if self.track is not None:  # the goal it steers by (:meth:`_goal`)
            goal = self.track.goals()[int(agent.rsplit("_", 1)[1])]
            rel = goal - odom[:2]
        else:
            rel = np.array([self.layout.get(obs, "goal_dx")[0], self.layout.get(obs, "goal_dy")[0]])
            goal = odom[:2] + rotate(rel, odom[2])
        if np.hypot(*rel) > reach:
            return None
        kpois = self.mission.kpois
        if not len(kpois):
            return None
        k = int(np.argmin(np.hypot(*(kpois - goal).T)))
        near = np.hypot(*(kpois[k] - goal)) <= self.mission.waypoint_tol
        return k if near and (agent, k) not in self.checked else None

    def _follow(self, agent: str, obs: np.ndarray) -> tuple[float, float]:
        g, f = self.layout.get, self.scenario.formation
        rel = np.array([g(obs, "pred_dx")[0], g(obs, "pred_dy")[0]])
        heading = float(atan2(g(obs, "pred_sin")[0], g(obs, "pred_cos")[0]))
        est = self.estimators.setdefault(agent, LeaderVelocityEstimator(self.dt))
        v_l, w_l = est.update(rel, heading, float(g(obs, "v")[0]), float(g(obs, "omega")[0]))
        m = relative_l_psi(rel, heading, f.offset)
        return l_psi_control(m, f.spacing, np.radians(f.bearing_deg), f.offset, f.gains, v_l, w_l,
                             self.v_max, self.w_max, min_speed=self.cfg.follower_min_speed * self.v_max)

    def _avoid(self, agent: str, obs: np.ndarray, v: float, w: float) -> tuple[float, float]:
        """Brake on the front sonar beams; back off and turn after being blocked too long."""
        if self.backing.get(agent, 0) > 0:
            self.backing[agent] -= 1
            return -self.cfg.backoff_speed * self.v_max, self.cfg.backoff_turn * self.w_max
        if self.sonar_front is None or v <= 0:
            self.blocked[agent] = 0
            return v, w
        front = float(np.min(self.layout.get(obs, "sonar")[self.sonar_front]))
        factor = brake_factor(front, self.stop, self.slow)
        self.blocked[agent] = self.blocked.get(agent, 0) + 1 if factor < 0.2 else 0
        limit = (self.cfg.patience + self.cfg.patience_stagger * int(agent.rsplit("_", 1)[1])) / self.dt
        if self.blocked[agent] > limit:
            self.blocked[agent] = 0
            self.backing[agent] = int(round(self.cfg.backoff_time / self.dt))
        return v * factor, w


def route_length(route: np.ndarray) -> float:
    """Length (m) of the polyline ``route (M, 2)``."""
    return float(np.hypot(*np.diff(np.asarray(route, dtype=float), axis=0).T).sum())


def route_from(route: np.ndarray, s: float) -> np.ndarray:
    """The part ``(K, 2)`` (at least two points) of the polyline ``route (M, 2)`` from arc length ``s`` (m) on:
    the point at ``s``, then the later vertices; past the end, the end point twice."""
    route = np.asarray(route, dtype=float)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(route, axis=0).T))])
    if s >= arc[-1]:
        return np.vstack([route[-1], route[-1]])
    k = int(np.searchsorted(arc, max(s, 0.0), side="right")) - 1
    u = (max(s, 0.0) - arc[k]) / max(arc[k + 1] - arc[k], 1e-12)
    return np.vstack([route[k] + u * (route[k + 1] - route[k]), route[k + 1:]])


def steer_point(way: np.ndarray, xy: np.ndarray, reach: float) -> np.ndarray:
    """The point to steer for from ``xy`` along the path ``way (K, 2)``: the vertex after the last one
    within ``reach`` (m) of ``xy`` (its last vertex if that is within reach; its first if none is)."""
    way = np.asarray(way, dtype=float)
    near = np.flatnonzero(np.hypot(*(way - xy).T) <= reach)
    return way[min(int(near[-1]) + 1, len(way) - 1) if len(near) else 0].copy()


def route_upto(route: np.ndarray, s: float, point: np.ndarray, tol: float) -> np.ndarray | None:
    """The polyline ``route (M, 2)`` from its start to its first vertex within ``tol`` (m) of ``point`` at
    or beyond arc length ``s`` (m; the vertex the robot at progress ``s`` heads for: out-and-back
    routes pass a vertex twice), or None if no vertex there lies that near ``point``."""
    route = np.asarray(route, dtype=float)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(route, axis=0).T))])
    at = np.flatnonzero((np.hypot(*(route - np.asarray(point, dtype=float)).T) <= tol) & (arc >= s - 1e-9))
    return route[: int(at[0]) + 1] if len(at) else None


def route_tree_waypoint(routes, xy: np.ndarray, target: np.ndarray, walls: np.ndarray) -> np.ndarray | None:
    """The vertex of the plan's route tree to head for from ``xy`` toward the route vertex
    ``target``: among the vertices of all ``routes`` in line of sight of ``xy`` (no wall of
    ``walls`` between), the one minimizing straight distance plus distance along the tree to
    ``target``; None if no vertex is in sight or ``target`` is not a vertex. The routes share their
    common prefix (they all start at the start), so the tree joins them at the turning positions."""
    import networkx as nx

    graph = nx.Graph()
    for route in routes:
        pts = [tuple(p) for p in np.asarray(route, dtype=float)]
        for a, b in zip(pts[:-1], pts[1:], strict=True):
            graph.add_edge(a, b, weight=float(np.hypot(b[0] - a[0], b[1] - a[1])))
    key = tuple(np.asarray(target, dtype=float))
    if key not in graph:
        return None
    along = nx.single_source_dijkstra_path_length(graph, key, weight="weight")
    nodes = np.array(list(along))
    seen = ~segments_blocked(np.repeat(np.asarray(xy, dtype=float)[None], len(nodes), axis=0), nodes, walls)
    if not seen.any():
        return None
    cost = np.hypot(*(nodes - xy).T) + np.array([along[tuple(n)] for n in nodes])
    cost[~seen] = np.inf
    return nodes[int(np.argmin(cost))]
