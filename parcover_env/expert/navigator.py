"""SonarNavigator: Kim, Pearce & Amato's NAVIGATOR loop (Fig. 1) as a policy over the env's observations.

    while goal not reached:  optimize the subgoal on the path (scan angle, eq. 1) -> replicate it for
    the team (parallel paths) -> rearrange subgoals (§3.2, §4) -> drive all robots
    to their subgoals and stop -> scan and localize one by one -> restart from the corrected poses.

Inputs, all explicit (never env internals): the scenario (the *known* map, robot and sonar models,
formation spacing), each robot's route ``plan.paths[i]``, the control period and the sonar beam
angles; per step only the observations (odometry pose, sonar ring ranges).

Design choices (documented deviations):
* Pose belief = a per-robot rigid correction on top of the odometry pose. A fix ``f`` at odometry
  pose ``o`` sets the correction to ``f o^-1``; the uncertainty ellipse (``Ellipse.grow``) grows with
  the odometry distance and rotation since the last fix.
* Parallel paths (§2, :mod:`~parcover_env.localization.sonar.parallel_paths`): robot i's path is its
  route translated sideways by its lane offset, lanes ``2 radius + slow_margin`` apart (a teammate
  beside a robot stays just outside the distance, radius + ``slow_margin``, at which the side beams
  turn it away) where the lane keeps radius + ``slow_margin`` from the walls; elsewhere the lanes
  merge onto the route over a ramp of twice the larger of the lane spacing and the column lag, and
  robot i trails ``i * formation.spacing`` there. All robots share the route's arclength labels, so
  one team label ``sigma`` puts them abreast. ``sigma`` minimizes the worst robot's bias (§3
  "optimizes the scan angle for all robots") within the horizon where every robot's ellipse stays
  below ``max_axis`` and its predicted uncertainty region does not hit a wall (§3.1's original rule,
  :mod:`~parcover_env.expert.horizon`); subgoals of robots that block each other are then
  rearranged (:mod:`~parcover_env.expert.rearrange`).
* Scan: the robot turns in place; every control step each ring beam's reading is binned by the
  odometry heading into the 72 bins of 5 deg (the reading nearest each bin centre is kept). The turn
  stops once every bin holds a reading within ``bin_tol_deg`` of its centre (with 8 beams this takes
  the largest gap between beams, ~80 deg, like the paper's two-sonar half turn), or after a full turn.
* Localization (Fig. 6) with relaxed sectors of rule 2, cached per map; other robots are unknown
  obstacles. The uncertainty region searched is the Kim, Pearce & Amato ellipse widened to ``region_sigmas`` of
  the belief's covariance, propagated from the last fix with the robot's odometry model (Chong &
  Kleeman): realistic drift outgrows the linear Kim, Pearce & Amato ellipse. A failed localization keeps the
  belief (the ellipse keeps growing); the next subgoal is then at least ``min_advance`` ahead so the
  robot scans from a new place.
"""

from __future__ import annotations

import math

import numpy as np

from parcover_env.config import Scenario
from parcover_env.control.leader import go_to_goal
from parcover_env.envs.observations import ObservationLayout
from parcover_env.expert.avoidance import brake_factor, lane_gap, sidestep, turn_away
from parcover_env.expert.config import NavigatorConfig, expert_config
from parcover_env.expert.horizon import RegionModel, collision_horizon
from parcover_env.expert.navigator_scans import NavigatorScans
from parcover_env.expert.rearrange import SubgoalRearranger
from parcover_env.expert.sonar_fix import belief_covariance_step, covariance_from_entries
from parcover_env.expert.team_localizer import TeamLocalizer
from parcover_env.geometry import wrap_angle
from parcover_env.geometry.poses import compose as _compose
from parcover_env.localization.sonar.config import sonar_localizer_config
from parcover_env.localization.sonar.localizer import Ellipse
from parcover_env.localization.sonar.parallel_paths import lane_offsets, lateral_offset, parallel_path, with_start
from parcover_env.localization.sonar.params import SonarLocalizerParams
from parcover_env.localization.sonar.subgoals import PathNodes, densify, score_nodes, team_subgoal

NavigatorParams = NavigatorConfig
"""Former name of :class:`~parcover_env.expert.config.NavigatorConfig` (the scenario's ``expert.navigator``)."""

__all__ = ["NavigatorConfig", "NavigatorParams", "SonarNavigator"]


class SonarNavigator(NavigatorScans):
    """Kim, Pearce & Amato NAVIGATOR policy: ``for_env(env)``, ``reset(obs)``, ``act(obs) -> actions``, ``stats()``."""

    def __init__(self, layout: ObservationLayout, scenario: Scenario, paths: list[np.ndarray],
                 control_dt: float, sonar_angles: np.ndarray, params: NavigatorConfig | None = None,
                 localizer: SonarLocalizerParams | None = None):
        if sonar_angles is None or len(sonar_angles) == 0:
            raise ValueError("SonarNavigator needs the sonar beam angles (observation.sonar must be on)")
        if "sonar" not in layout.slices:
            raise ValueError("SonarNavigator needs a 'sonar' entry in the observation layout")
        if not control_dt > 0:
            raise ValueError(f"control_dt must be > 0, got {control_dt}")
        if len(paths) == 0:
            raise ValueError("SonarNavigator needs one route per robot, got none")
        self.layout, self.scenario, self.dt = layout, scenario, float(control_dt)
        self.p = params if params is not None else expert_config(scenario).navigator
        self.loc = localizer or sonar_localizer_config(scenario)
        self.beams = np.asarray(sonar_angles, dtype=float)
        r = scenario.robot
        self.sonar_cfg = r.sonar
        self.v_max, self.w_max, self.radius = r.max_speed, r.max_turn_rate, r.radius
        self.spacing = scenario.formation.spacing
        self.team_loc = TeamLocalizer(scenario, self.p, self.loc)
        self.map, self.features = self.team_loc.map, self.team_loc.features
        self.n_bins = self.team_loc.n_bins
        self.step_rad = math.radians(r.sonar.scan_step_deg)
        self.specular = r.sonar.model == "specular"
        self.incidence = math.radians(r.sonar.incidence_max_deg) if self.specular else math.pi / 2
        self.cone = math.radians(r.sonar.cone_deg) if self.specular else 0.0
        self.front = np.flatnonzero(np.abs(wrap_angle(self.beams)) <= math.radians(self.p.front_sector_deg))
        self.side = np.flatnonzero(np.abs(np.abs(wrap_angle(self.beams)) - math.pi / 2)
                                   <= math.radians(self.p.side_sector_deg))
        self.odometry, self.wheel_base = r.odometry, r.drive.wheel_base
        fx = expert_config(scenario).sonar_fix
        self.fix_cov = np.diag([fx.fix_sigma**2, fx.fix_sigma**2, math.radians(fx.fix_sigma_heading_deg) ** 2])
        self.routes = [np.asarray(p, dtype=float) for p in paths]
        self.n = len(self.routes)
        self.lane_spacing = 2 * self.radius + self.p.slow_margin
        """Distance between neighbouring lanes of the parallel paths (m)."""
        self.lane_clearance = self.radius + self.p.slow_margin
        """A lane keeps this from the known map's walls, else it merges onto the route (m)."""
        self.region_model = RegionModel(self.p, self.fix_cov, self.odometry, self.wheel_base, self.map, self.radius)
        self.env_scan = "scanning" in layout.slices
        """Scan through the env's sonar localization service (``observation.scan``): the robot asks
        with the ``scan`` action component, is held still while the ``scanning`` entry is 1, and the
        env's estimate (the observed pose) and covariance (the ``sigma_*`` entries) carry the fix;
        otherwise the navigator turns, collects and localizes each scan itself."""
        self.env_cov = self.env_scan and "sigma_major" in layout.slices
        """The env's covariance is observed (``observation.pose_covariance``; off in the ``ideal``
        preset): else the navigator propagates its own from the last fix, also with the env's scans."""
        self.rearranger = SubgoalRearranger(self.features, self.team_loc.sectors, self.map, self.radius,
                                            r.sonar.range_max, self.incidence, self.cone, self.p)
        self.reset()

    @classmethod
    def for_env(cls, env, **kwargs) -> SonarNavigator:
        """Build from an env's public spec: layout, scenario, plan routes, control period, sonar beams."""
        if env.sonar is None:
            raise ValueError("SonarNavigator needs an env with sonar observations (observation.sonar: true)")
        return cls(env.layout, env.scenario, list(env.plan.paths), env.scenario.physics.control_dt,
                   env.sonar.beam_angles, **kwargs)

    # ------------------------------------------------------------------ episode
    def reset(self, observations: dict[str, np.ndarray] | None = None) -> None:
        n = self.n
        self.correction = np.zeros((n, 3))
        self.last_odom: np.ndarray | None = None
        self.raw, self.offset = np.zeros((n, 3)), np.zeros((n, 2))  # last observed poses; clipping offsets
        self.travelled = np.zeros(n)
        self.turned = np.zeros(n)
        self.axis0 = np.full(n, self.p.initial_axis)
        self.cov = np.repeat(self.fix_cov[None], n, axis=0)
        """Covariances ``(N, 3, 3)`` of the beliefs, propagated from the last fix with the odometry model."""
        self.paths: list[PathNodes] | None = None
        self.progress = np.zeros(n)
        self.targets = np.zeros(n)
        self.goal_xy = np.full((n, 2), np.nan)  # a subgoal off the path (bisector rearrangement), NaN: none
        self.sigma = 0.0
        self.done = np.zeros(n, dtype=bool)
        self.final_scans = np.zeros(n, dtype=int)
        self.phase = "plan"
        self.arrived = np.zeros(n, dtype=bool)
        self.drive_steps, self.drive_limit = 0, 0
        self.queue: list[int] = []
        self.scan: dict | None = None
        self.request = np.zeros(n, dtype=bool)
        """Robots that ask the env for a scan at this step (:attr:`env_scan`)."""
        self.fixes: list[dict] = []
        self._stats = {"scans": 0, "localized": 0, "failed": 0, "corrections": [], "scan_steps": 0,
                       "rearranged": 0, "iterations": 0, "bias": [], "lateral": [], "apart": 0, "close": 0,
                       "reacted": 0}
        if observations:
            self._ingest(observations)

    def stats(self) -> dict:
        """Counters for the episode summary (prefixed ``sonar_``). ``sonar_rearranged``: robot pairs
        whose subgoals were rearranged (§3.2), ``sonar_rearranged_close`` those of them the proximity
        trigger fired (our extension), ``sonar_reacted`` robots whose subgoal moved because a done
        teammate stood in their scan (our extension); ``sonar_separate_sectors``: pairs whose subgoals lay in
        different relaxed sectors (Fig. 10: no rearrangement). ``sonar_bias_before_deg`` / ``_after_deg``: mean eq. 1
        bias (deg) over the robots' subgoals chosen by the scan-angle optimization, at the node the
        original algorithm takes (the last within the horizon) and at the optimized one (before any
        rearrangement); subgoals without an available feature at either node are left out
        (``sonar_bias_subgoals`` counts the rest). ``sonar_lateral_offset``: median distance (m)
        between robots 0 and 1 across their mean heading, by belief, over the steps both drive."""
        st, c, b = self._stats, self._stats["corrections"], np.array(self._stats["bias"]).reshape(-1, 2)
        return {"sonar_scans": st["scans"], "sonar_localized": st["localized"], "sonar_failed": st["failed"],
                "sonar_mean_correction": float(np.mean(c)) if c else 0.0,
                "sonar_scan_time": st["scan_steps"] * self.dt,
                "sonar_rearranged": st["rearranged"], "sonar_rearranged_close": st["close"],
                "sonar_reacted": st["reacted"], "sonar_separate_sectors": st["apart"],
                "sonar_iterations": st["iterations"],
                "sonar_bias_before_deg": float(np.degrees(b[:, 0].mean())) if len(b) else math.nan,
                "sonar_bias_after_deg": float(np.degrees(b[:, 1].mean())) if len(b) else math.nan,
                "sonar_bias_subgoals": len(b),
                "sonar_lateral_offset": float(np.median(st["lateral"])) if st["lateral"] else math.nan}

    def belief(self) -> np.ndarray:
        """``(N, 3)`` current pose beliefs (correction applied to the last odometry poses)."""
        if self.last_odom is None:
            raise RuntimeError("belief() before the first observation")
        return np.array([_compose(self.correction[i], self.last_odom[i]) for i in range(self.n)])

    def ellipse(self, i: int) -> Ellipse:
        """Robot ``i``'s uncertainty ellipse around its belief."""
        e = Ellipse(tuple(self.belief()[i, :2]), (self.axis0[i], self.axis0[i]))
        return e.grow(self.travelled[i], self.turned[i], self.p.rate_distance, self.p.rate_rotation)

    def region(self, i: int, center) -> Ellipse:
        """Where robot ``i``'s scan is localized: the ``region_sigmas`` ellipse of its belief's
        covariance, widened in every direction by its Kim, Pearce & Amato ellipse's semi-axis (so it holds both)."""
        k = self.p.region_sigmas
        grown = max(self.ellipse(i).axes)
        return Ellipse.from_covariance(center, self.cov[i][:2, :2] + (grown / k) ** 2 * np.eye(2), k)

    def subgoals(self) -> np.ndarray:
        """``(N, 2)`` current subgoal positions (the route starts before the first plan)."""
        if self.paths is None:
            return np.array([r[0] for r in self.routes])
        on = np.array([p.point(t) for p, t in zip(self.paths, self.targets, strict=True)])
        return np.where(np.isfinite(self.goal_xy), self.goal_xy, on)

    # ------------------------------------------------------------------ act
    def act(self, observations: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        self._ingest(observations)
        cmd = np.zeros((self.n, 2))
        self.request[:] = False
        if self.phase == "plan" and not self.done.all():
            self._plan()
        if self.phase == "drive":
            self._drive(observations, cmd)
        if self.phase == "scan":
            self._scan_step(observations, cmd)
        out = {}
        for a in observations:
            i = int(a.rsplit("_", 1)[1])
            out[a] = np.array([cmd[i, 0] / self.v_max, cmd[i, 1] / self.w_max], dtype=np.float32)
            if self.env_scan:  # the env's sonar localization service: (v, w, scan)
                out[a] = np.append(out[a], np.float32(1.0 if self.request[i] else -1.0))
        return out

    def _ingest(self, observations: dict[str, np.ndarray]) -> None:
        """Odometry poses from the observations. The observed x, y are clipped to the map box +- 1 m
        and a long mission's odometry drifts beyond it: a step whose x or y reading is (or was) at
        that bound moves by the encoder speed ``v`` along the mid-step heading instead."""
        g, lay = self.layout.get, self.layout
        lo, hi = (np.array([b[lay.slices[k]][0] for k in ("x", "y")]) for b in (lay.low, lay.high))
        odom = np.zeros((self.n, 3)) if self.last_odom is None else self.last_odom.copy()
        for a, o in observations.items():
            i = int(a.rsplit("_", 1)[1])
            if not 0 <= i < self.n:
                raise ValueError(f"observation for unknown agent {a!r} ({self.n} routes)")
            raw = np.array([g(o, "x")[0], g(o, "y")[0], math.atan2(g(o, "sin_theta")[0], g(o, "cos_theta")[0])])
            if self.last_odom is not None and np.any((raw[:2] <= lo) | (raw[:2] >= hi)
                                                     | (self.raw[i, :2] <= lo) | (self.raw[i, :2] >= hi)):
                mid = self.raw[i, 2] + 0.5 * float(wrap_angle(raw[2] - self.raw[i, 2]))
                odom[i, :2] += float(g(o, "v")[0]) * self.dt * np.array([math.cos(mid), math.sin(mid)])
                self.offset[i] = odom[i, :2] - raw[:2]  # odometry pose = observed + offset from now on
            else:
                odom[i, :2] = raw[:2] + self.offset[i]
            odom[i, 2], self.raw[i] = raw[2], raw
        if self.env_cov:  # the env's covariance of its estimate, from the observation
            names = ("sigma_major", "sigma_minor", "sigma_axis_cos2", "sigma_axis_sin2", "sigma_heading")
            for a, o in observations.items():
                i = int(a.rsplit("_", 1)[1])
                self.cov[i] = covariance_from_entries(np.array([g(o, k)[0] for k in names], dtype=float), odom[i, 2])
        if self.last_odom is not None:
            if not self.env_cov:
                heading = self.last_odom[:, 2] + self.correction[:, 2]
                self.cov = belief_covariance_step(self.cov, self.last_odom, odom, heading, self.odometry,
                                                  self.wheel_base)
            self.travelled += np.hypot(*(odom[:, :2] - self.last_odom[:, :2]).T)
            self.turned += np.abs(wrap_angle(odom[:, 2] - self.last_odom[:, 2]))
        self.last_odom = odom
        moving = [f"robot_{i}" in observations and not self.arrived[i]
                  and abs(float(g(observations[f"robot_{i}"], "v")[0])) > self.p.stop_speed
                  for i in range(min(self.n, 2))]
        if self.phase == "drive" and len(moving) == 2 and all(moving):
            bel = self.belief()
            self._stats["lateral"].append(lateral_offset(bel[:2, :2], bel[:2, 2]))
        if self.paths is None:
            self._build_paths()

    def _build_paths(self) -> None:
        """Robot i's path: its start (if off its lane) then its lane, the parallel path of its route;
        arclength label 0 at the route start."""
        lags = np.arange(self.n) * self.spacing
        ramp = 2 * max(self.lane_spacing, float(lags.max()))
        offsets = lane_offsets(self.n, self.lane_spacing)
        self.paths = [with_start(parallel_path(densify(route, self.p.node_step), offsets[i], self.map,
                                               self.lane_clearance, ramp, lag=lags[i]),
                                 self.last_odom[i, :2], self.p.node_step) for i, route in enumerate(self.routes)]
        self.scores = [score_nodes(p.xy, self.map, self.features, self.sonar_cfg.range_min,
                                   self.sonar_cfg.range_max, self.step_rad, self.incidence,
                                   self.p.min_wall_length, self.p.min_readings, self.p.min_walls_seen,
                                   self.p.range_margin) for p in self.paths]
        self.lags = np.zeros(self.n)  # the lanes' labels hold the lags where lanes merge
        self.progress = np.array([p.s[0] for p in self.paths])
        self.targets = self.progress.copy()

    def _update_progress(self, i: int, xy: np.ndarray) -> None:
        p = self.paths[i]
        win = np.nonzero((p.s >= self.progress[i] - 0.5) & (p.s <= self.progress[i] + 1.0))[0]
        if len(win) == 0:
            win = np.arange(len(p.s))
        k = win[np.argmin(np.hypot(*(p.xy[win] - xy).T))]
        self.progress[i] = p.s[k]

    # ------------------------------------------------------------------ Fig. 1 lines 3-6
    def _plan(self) -> None:
        bel = self.belief()
        active = np.nonzero(~self.done)[0]
        for i in active:
            self._update_progress(i, bel[i, :2])
        axes = np.array([max(self.ellipse(i).axes) for i in range(self.n)])
        horizon = np.maximum(self.p.min_advance, (self.p.max_axis - axes) / self.p.rate_distance)
        for i in active:  # §3.1's original rule: stop before the uncertainty region would hit a wall
            reach = collision_horizon(self.paths[i], self.progress[i], self.progress[i] + horizon[i], self.cov[i],
                                      self.travelled[i], self.turned[i], self.axis0[i], self.region_model)
            horizon[i] = max(self.p.min_advance, reach - self.progress[i])
        ends = np.array([p.s[-1] for p in self.paths])
        sigma_end = float(np.max(ends + self.lags))
        sigma_hi = float(np.min(self.progress[active] + horizon[active] + self.lags[active]))
        sigma_lo = min(self.sigma + self.p.min_advance, sigma_hi)
        if sigma_hi >= sigma_end:
            sigma = sigma_end
        else:
            sigma = team_subgoal([self.paths[i] for i in active], [self.scores[i].bias for i in active],
                                 self.lags[active], sigma_lo, sigma_hi, self.p.node_step,
                                 math.radians(self.p.tie_tol_deg))
            for i in active:  # §3.1: the original algorithm's node (the last within the horizon) vs eq. 1's
                b = [self.scores[i].bias[self.paths[i].index(t)] for t in (sigma_hi, sigma)]
                if np.all(np.isfinite(b)):
                    self._stats["bias"].append(b)
        self.sigma = sigma
        starts = np.array([p.s[0] for p in self.paths])
        targets = np.clip(sigma - self.lags, starts, ends)
        targets[self.done] = ends[self.done]
        windows = np.stack([self.progress, np.minimum(self.progress + horizon, ends)], axis=1)
        res = (self.rearranger.rearrange(self.paths, self.scores, targets, windows, active, standing=bel[self.done, :2])
               if self.n > 1 else None)  # done teammates stand where their runs left them (our extension)
        self.targets = targets if res is None else res.targets
        self.goal_xy = np.full((self.n, 2), np.nan) if res is None else res.goals
        self._stats["rearranged"] += 0 if res is None else res.pairs
        self._stats["close"] += 0 if res is None else res.close
        self._stats["reacted"] += 0 if res is None else len(res.reacted)
        self._stats["apart"] += 0 if res is None else res.apart
        self.phase, self.arrived = "drive", self.done.copy()
        self.drive_steps = 0
        dist = np.abs(self.targets - self.progress).max()
        self.drive_limit = int((dist / (0.5 * self.v_max) + self.p.drive_timeout) / self.dt)
        self._stats["iterations"] += 1

    # ------------------------------------------------------------------ Fig. 1 line 7
    def _drive(self, observations, cmd: np.ndarray) -> None:
        bel = self.belief()
        self.drive_steps += 1
        for i in range(self.n):
            if self.arrived[i] or f"robot_{i}" not in observations:
                continue
            p = self.paths[i]
            self._update_progress(i, bel[i, :2])
            off_path = bool(np.isfinite(self.goal_xy[i, 0]))
            goal_pt = self.goal_xy[i] if off_path else p.point(self.targets[i])
            if np.hypot(*(goal_pt - bel[i, :2])) < self.p.arrive_tol:
                self.arrived[i] = True
                continue
            ahead = self.targets[i] - self.progress[i]
            look = p.point(self.progress[i] + math.copysign(min(self.p.lookahead, abs(ahead)), ahead))
            if np.hypot(*(goal_pt - bel[i, :2])) < self.p.lookahead or (off_path and abs(ahead) < self.p.lookahead):
                look = goal_pt
            d = self._bypass(i, bel, look - bel[i, :2])
            c, s = math.cos(bel[i, 2]), math.sin(bel[i, 2])
            v, w = go_to_goal(np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]), self.v_max, self.w_max)
            if v > 0:
                v *= min(self._brake(observations[f"robot_{i}"]), self._team_brake(i, bel))
                w = float(np.clip(w + self._side_turn(observations[f"robot_{i}"]), -self.w_max, self.w_max))
            cmd[i] = [v, w]
        if self.arrived.all() or self.drive_steps > self.drive_limit:
            self.arrived[:] = True
            self.queue = [i for i in range(self.n) if not self.done[i]]
            self.phase = "scan"
            cmd[:] = 0.0

    def _lane(self, i: int, bel: np.ndarray, heading: float) -> tuple[float, int]:
        """``(gap, j)``: the nearest teammate ``j`` in the lane robot ``i`` sweeps along ``heading``
        (two radii + ``stop_margin`` wide; :func:`lane_gap`), by the believed positions."""
        return lane_gap(bel[:, :2], i, heading, 2 * self.radius + self.p.stop_margin, 2 * self.radius)

    def _team_brake(self, i: int, bel: np.ndarray) -> float:
        """Slow down for a teammate in robot ``i``'s lane (:meth:`_lane`). A teammate beside the lane is
        no obstacle: braking for it would deadlock two robots that pass each other."""
        gap, _ = self._lane(i, bel, float(bel[i, 2]))
        return brake_factor(gap, self.p.stop_margin, self.p.slow_margin)

    def _bypass(self, i: int, bel: np.ndarray, d: np.ndarray) -> np.ndarray:
        """The direction robot ``i`` drives instead of ``d`` (its way to the look-ahead point) when a
        teammate ``j`` stands in that lane at the stop distance and will not move out of it: ``j`` has
        arrived at its subgoal (or is done), or ``i`` stands in ``j``'s lane too (each would wait for
        the other forever). ``i`` then steps sideways (:func:`sidestep`) until its lane gap exceeds
        the stop distance."""
        gap, j = self._lane(i, bel, math.atan2(d[1], d[0]))
        if j < 0 or gap > self.p.stop_margin:
            return d
        if not (self.arrived[j] or self.done[j] or self._lane(j, bel, float(bel[j, 2]))[1] == i):
            return d
        return sidestep(bel[i, :2], bel[j, :2], d)

    def _side_turn(self, obs: np.ndarray) -> float:
        """Turn rate (rad/s) away from the nearest side echo (beams within ``side_sector_deg`` of
        +-90 deg; :func:`turn_away` between radius + ``stop_margin`` and radius + ``slow_margin``). A
        heading error of a few degrees takes a robot into a corridor wall that its front beams,
        meeting the wall at grazing incidence, never see."""
        return turn_away(self.layout.get(obs, "sonar")[self.side], self.beams[self.side],
                         self.radius + self.p.stop_margin, self.radius + self.p.slow_margin, self.w_max)

    def _brake(self, obs: np.ndarray) -> float:
        if len(self.front) == 0:
            return 1.0
        front = float(np.min(self.layout.get(obs, "sonar")[self.front]))
        return brake_factor(front, self.radius + self.p.stop_margin, self.radius + self.p.slow_margin)

    # ------------------------------------------------------------------ Fig. 1 line 9
    def _end_iteration(self) -> None:
        """Fig. 1 line 9: start again from the robots' corrected configurations."""
        self.phase = "plan"

