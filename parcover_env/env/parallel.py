"""ParallelCoverageEnv: the PettingZoo ParallelEnv of the parallel path coverage mission."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from parcover_env.config import Scenario
from parcover_env.env.actions import to_commands
from parcover_env.env.metrics import EpisodeMetrics, formation_errors
from parcover_env.env.observations import MAX_FIX_AGE, ObservationLayout
from parcover_env.env.rewards import TERMS, reward_terms
from parcover_env.env.team import Team
from parcover_env.geometry import rotate
from parcover_env.localization.kinect.system import KinectSystem
from parcover_env.scenarios import load_scenario, mission_for
from parcover_env.sensors.odometry import Odometry
from parcover_env.sensors.relative import RelativeCamera
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.physics import World

__all__ = ["ParallelCoverageEnv"]


class ParallelCoverageEnv(ParallelEnv):
    """Parallel path coverage: a team of differential-drive robots, starting together, must visit
    every Key Position Of Interest (KPOI) of an indoor map (Min, Fehr & Papanikolopoulos; Kim,
    Pearce & Amato). PettingZoo ``ParallelEnv``; agents ``robot_0 .. robot_{n-1}``.

    ## Scenario
    A YAML scenario (``office``, ``tree``, ``hallway``, ``t_room``, a path, or a ``Scenario``)
    gives the map (walls and obstacles, metres), start pose, KPOIs, overhead Kinects, robot model,
    team size (``n_robots: auto`` = the PPCP planner's optimal r), rates, limits and reward weights.
    The PPCP plan (``parcover_env.planning``) gives every robot a route: a polyline from the start
    through its KPOIs; the team travels together and splits at turning positions (TPs).

    ## Action space
    ``Box(-1, 1, (2,), float32)`` per agent: ``(v, omega)`` as fractions of the robot's
    ``max_speed`` (m/s) and ``max_turn_rate`` (rad/s). Values outside [-1, 1] are clipped; NaN/inf,
    a wrong shape, or missing/unknown agents raise ``ActionError`` and leave the state untouched.

    ## Observation space
    One flat ``Box`` per agent, identical across agents (``env.layout`` names the slices):

    | entry | size | unit | meaning |
    |---|---|---|---|
    | x, y | 2 | m | pose estimate: odometry, reset by Kinect fixes of seen leaders (``pose_source``) |
    | cos_theta, sin_theta | 2 | - | heading estimate |
    | v, omega | 2 | m/s, rad/s | velocity commanded at the last step |
    | leader | 1 | - | 1 if the robot leads its group, else 0 (follower) |
    | slot | 1 | - | position in its group's column / (n_robots - 1); 0 = leader |
    | pred_dx, pred_dy | 2 | m | robot ahead in the column, in this robot's frame (onboard camera; 0 if unseen) |
    | pred_cos, pred_sin | 2 | - | its heading relative to this robot's |
    | pred_visible | 1 | - | 1 if a follower's camera sees its predecessor (FOV, range, walls) |
    | fix_age | 1 | s | time since the last absolute pose fix, capped at 60 s (large = stale estimate) |
    | goal_dx, goal_dy | 2 | m | current route waypoint in the robot frame (x ahead, y left), from the estimate |
    | kpois_visited | 1 | - | fraction of KPOIs visited by the team |
    | time | 1 | - | fraction of the step limit elapsed |
    | sonar | B | m | sonar ring ranges (B beams; ``robot.sonar``), max range = no echo |

    ``state()`` is the global state for centralized critics: true (x, y, cos, sin) and leader
    flag of every robot, the visited flag of every KPOI, and the elapsed time fraction.

    ## Rewards
    Per agent, the sum of named terms whose weights come from ``rewards`` in the scenario and which
    are reported in ``info[agent]["reward_terms"]``: ``kpoi`` (per KPOI newly visited by anyone,
    team reward), ``progress`` (per metre of route-to-go removed, potential-based), ``time`` (per
    step), ``collision`` (per new contact of this agent with a wall or robot). A KPOI is visited
    when a robot's true centre comes within ``kpoi_radius`` of it.

    ## Episode end
    Terminated when every KPOI is visited; truncated after ``episode.max_steps`` control steps.
    All agents end together; ``info[agent]["episode"]`` then holds the metrics (makespan, KPOIs
    visited, collisions, path lengths, localization error, makespan / (c_max / v_max), ...).

    ## Rates
    One ``step`` is one control period of ``physics.substeps x physics.dt`` seconds (default
    5 x 0.02 s = 0.1 s); pymunk integrates at ``physics.dt``.

    ## Arguments
    ``scenario`` (name, path or Scenario, default ``"office"``), ``render_mode`` (``None`` or
    ``"rgb_array"``), ``overrides`` (nested dict merged over the scenario, e.g.
    ``{"n_robots": 3, "episode": {"max_steps": 500}}``).

    ## Version history
    * v0: initial release.
    """

    metadata = {"name": "parcover_v0", "render_modes": ["rgb_array"], "render_fps": 10, "is_parallelizable": True}

    def __init__(self, scenario: str | Path | Scenario = "office", render_mode: str | None = None,
                 overrides: dict | None = None, preset: str = "realistic"):
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.scenario = load_scenario(scenario, overrides, preset)
        self.render_mode = render_mode
        s = self.scenario
        self.mission = mission_for(s)
        self.map, self.known_map, self.plan = self.mission.map, self.mission.known_map, self.mission.plan
        self.n_robots = self.plan.r
        self.possible_agents = [f"robot_{i}" for i in range(self.n_robots)]
        self.agents: list[str] = []
        self.sonar = SonarRing(s.robot.sonar) if s.observation.sonar else None
        n_sonar = self.sonar.n_beams if self.sonar else 0
        self.kinects = KinectSystem(s, self.map) if s.kinects and s.observation.pose_source == "kinect" else None
        self.camera = RelativeCamera(s.formation.camera_fov_deg, s.formation.camera_range)
        self.layout = ObservationLayout.build(self.map.bounds, s.robot.max_speed, s.robot.max_turn_rate,
                                              n_sonar, s.robot.sonar.range_max, s.formation.camera_range)
        self._obs_space = self.layout.space()
        self._act_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        n_state = 5 * self.n_robots + len(s.kpois) + 1
        self.state_space = spaces.Box(-np.inf, np.inf, (n_state,), dtype=np.float32)
        self._rng: np.random.Generator | None = None

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent: str) -> spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Box:
        return self._act_space

    # ------------------------------------------------------------------ episode
    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        s = self.scenario
        self.agents = list(self.possible_agents)
        self.world = World(self.map, s.robot.radius, s.physics, self.mission.start_poses)
        true = self.world.poses()
        self.odometry = Odometry(s.robot.odometry, true)
        self.estimate = true.copy()
        self.fix_age = np.zeros(self.n_robots)
        if self.kinects is not None:
            self.kinects.reset()
        self.progress = self.mission.tracker()
        self.team = Team(self.plan, s.formation.mode, reach_tol=self.mission.reach_tol)
        self.commands = np.zeros((self.n_robots, 2))
        self.steps = 0
        self._contacts = np.zeros((2, self.n_robots), dtype=np.int64)
        self._remaining = self.progress.remaining(true[:, :2])
        self.metrics = EpisodeMetrics(len(s.kpois), self.n_robots, self.plan.c_max, s.robot.max_speed,
                                      path_lengths=[0.0] * self.n_robots)
        self.trails = [[p[:2].copy()] for p in true]
        self.progress.update(true[:, :2], self.estimate[:, :2], 0.0)
        self._update_team()
        obs = self._observe(true)
        infos = {a: {"plan": self.plan.to_dict()} for a in self.agents}
        return obs, infos

    def step(self, actions: dict[str, Any]):
        if not self.agents:
            raise RuntimeError("step() called on a finished episode; call reset() first")
        self.commands = to_commands(actions, self.agents, self.scenario.robot.max_speed,
                                    self.scenario.robot.max_turn_rate)
        before = self.world.poses()
        self.world.step(self.commands)
        self.steps += 1
        true = self.world.poses()
        self._sense(true)
        n_new = self.progress.update(true[:, :2], self.estimate[:, :2], self.world.time)
        self.team.count_waypoints(self.progress.advanced)
        self._update_team()
        terms = self._rewards(true, n_new)
        self._record(before, true)
        obs = self._observe(true)
        done = self.progress.done
        truncated = self.steps >= self.scenario.episode.max_steps and not done
        total = 0
        for t in TERMS:  # summed in TERMS order, as sum() over the terms of each agent would
            total = total + terms[t]
        rewards = dict(zip(self.agents, total.tolist(), strict=True))
        per_agent = zip(*(terms[t].tolist() for t in TERMS), strict=True)
        infos = {a: {"reward_terms": dict(zip(TERMS, vals, strict=True))}
                 for a, vals in zip(self.agents, per_agent, strict=True)}
        if done or truncated:
            summary = self.metrics.summary()
            for info in infos.values():
                info["episode"] = summary
        terminations = {a: done for a in self.agents}
        truncations = {a: truncated for a in self.agents}
        if done or truncated:
            self.agents = []
        return obs, rewards, terminations, truncations, infos

    # ------------------------------------------------------------------ step parts
    def _update_team(self) -> None:
        """Alg. 1: splits on the Kinect system's detections of leaders (estimates out of view)."""
        est = self.estimate[:, :2]
        if self.kinects is None:
            self.team.update(est, self.progress.plan_progress)
        else:
            self.team.update(est, self.progress.plan_progress, self.kinects.last_fixes, self.kinects.in_view(est))

    def _sense(self, true: np.ndarray) -> None:
        """Pose estimates: odometry dead reckoning, corrected by Kinect fixes of the leaders."""
        est = self.odometry.measure(true, self._rng)
        self.fix_age += self.scenario.physics.control_dt
        if self.scenario.observation.pose_source == "ground_truth":
            est[:] = true
            self.fix_age[:] = 0.0
        elif self.kinects is not None:
            markers = self.team.leader & self.scenario.robot.markers
            fixes = self.kinects.update(self.world.time, true, markers, est, self._rng)
            for i, pose in fixes.items():
                self.odometry.fix(i, pose)
                self.fix_age[i] = 0.0
            self.team.count_pose_fixes(len(fixes))
        self.estimate = est

    def _rewards(self, true: np.ndarray, n_new: int) -> dict[str, np.ndarray]:
        remaining = self.progress.remaining(true[:, :2])
        progress, self._remaining = self._remaining - remaining, remaining
        contacts = np.stack([self.world.wall_contacts, self.world.robot_contacts])
        new_contacts = (contacts - self._contacts).sum(axis=0)
        self._new_contacts, self._contacts = contacts - self._contacts, contacts
        return reward_terms(self.scenario.rewards, n_new, progress, new_contacts)

    def _record(self, before: np.ndarray, true: np.ndarray) -> None:
        m = self.metrics
        m.path_lengths = (np.asarray(m.path_lengths) + np.hypot(*(true[:, :2] - before[:, :2]).T)).tolist()
        m.record_step(self.world.time, int(self.progress.visited.sum()), true, self.estimate,
                      int(self._new_contacts[0].sum()), int(self._new_contacts[1].sum()) // 2)
        f = self.scenario.formation
        dl, dpsi = formation_errors(true, self.team.predecessor, f.offset, f.spacing, np.radians(f.bearing_deg))
        m.record_formation(dl, dpsi)
        m.messages = dict(sorted(self.team.messages.items()))
        m.kinect_splits, m.odometry_splits = self.team.splits["kinect"], self.team.splits["odometry"]
        seen = self.kinects.in_view(true[:, :2]) if self.kinects is not None else np.zeros(self.n_robots, bool)
        m.unseen_leader_time += self.scenario.physics.control_dt * int(np.count_nonzero(self.team.leader & ~seen))
        if self.progress.done and m.makespan is None:
            m.makespan = float(np.nanmax(self.progress.visit_time))
        if self.render_mode is not None:
            for trail, p in zip(self.trails, true):
                trail.append(p[:2].copy())

    def _observe(self, true: np.ndarray) -> dict[str, np.ndarray]:
        L, est, n = self.layout.slices, self.estimate, self.n_robots
        obs = np.zeros((n, self.layout.size), dtype=np.float32)
        obs[:, L["x"]] = est[:, 0:1]
        obs[:, L["y"]] = est[:, 1:2]
        obs[:, L["cos_theta"]] = np.cos(est[:, 2:3])
        obs[:, L["sin_theta"]] = np.sin(est[:, 2:3])
        obs[:, L["v"]] = self.commands[:, 0:1]
        obs[:, L["omega"]] = self.commands[:, 1:2]
        obs[:, L["leader"]] = self.team.leader[:, None]
        obs[:, L["slot"]] = self.team.slot[:, None] / max(n - 1, 1)
        obs[:, L["fix_age"]] = np.minimum(self.fix_age, MAX_FIX_AGE)[:, None]
        goal = rotate(self.progress.goals() - est[:, :2], -est[:, 2])
        obs[:, L["goal_dx"]] = goal[:, 0:1]
        obs[:, L["goal_dy"]] = goal[:, 1:2]
        rel = self.camera.measure(true, self.team.predecessor, self.map.segments, self._rng)
        obs[:, L["pred_dx"]] = rel.rel_xy[:, 0:1]
        obs[:, L["pred_dy"]] = rel.rel_xy[:, 1:2]
        obs[:, L["pred_cos"]] = np.where(rel.visible, np.cos(rel.rel_heading), 0.0)[:, None]
        obs[:, L["pred_sin"]] = np.where(rel.visible, np.sin(rel.rel_heading), 0.0)[:, None]
        obs[:, L["pred_visible"]] = rel.visible[:, None]
        obs[:, L["kpois_visited"]] = self.progress.visited.mean()
        obs[:, L["time"]] = self.steps / self.scenario.episode.max_steps
        if self.sonar is not None:
            obs[:, L["sonar"]] = self.sonar.measure(true, self.map.segments, self.scenario.robot.radius, self._rng)
        self.layout.clip(obs)
        if len(self.agents) == n:
            return dict(zip(self.possible_agents, obs, strict=True))
        active = set(self.agents)
        return {a: obs[i] for i, a in enumerate(self.possible_agents) if a in active}

    # ------------------------------------------------------------------ extras
    def state(self) -> np.ndarray:
        true = self.world.poses()
        parts = [true[:, :2], np.cos(true[:, 2:3]), np.sin(true[:, 2:3]), self.team.leader[:, None]]
        robots = np.concatenate(parts, axis=1).ravel()
        t = [self.steps / self.scenario.episode.max_steps]
        return np.concatenate([robots, self.progress.visited.astype(float), t]).astype(np.float32)

    def kinect_frames(self) -> dict:
        """Depth + IR frames (``KinectFrame``) of every overhead Kinect at the current state.

        With ``observation.kinect: frames`` these are the frames the pipeline localized from at the
        last Kinect tick; otherwise they are rendered now from a generator seeded by the step count,
        so calling this never changes the episode.
        """
        if self.kinects is None:
            return {}
        if self.scenario.observation.kinect == "frames" and self.kinects.frames:
            return dict(self.kinects.frames)
        markers = self.team.leader & self.scenario.robot.markers
        return self.kinects.render_frames(self.world.poses(), markers, seed=self.steps)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            return None
        from parcover_env.viz.render import render_frame

        return render_frame(self)

    def close(self) -> None:
        pass
