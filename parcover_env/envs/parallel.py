"""ParallelCoverageEnv: the PettingZoo ParallelEnv of the parallel path coverage mission."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from parcover_env.config import Scenario, deep_merge
from parcover_env.envs import critic_state
from parcover_env.envs.entry_checks import check_options, check_seed, require_episode
from parcover_env.envs.feature_sets import feature_set
from parcover_env.envs.obs_spec import markdown_table
from parcover_env.envs.observations import ObservationLayout, build_sensors
from parcover_env.errors import CallOrderError
from parcover_env.localization.estimator import KinectFixes, PoseEstimator
from parcover_env.localization.kinect.system import KinectSystem
from parcover_env.localization.sonar.service import SonarFixes
from parcover_env.mission.metrics import EpisodeMetrics
from parcover_env.mission.rewards import paid_terms
from parcover_env.mission.team import CameraView, Team, update_team
from parcover_env.scenarios import load_scenario, mission_for
from parcover_env.sensors.relative import RelativeCamera
from parcover_env.sim import act_phase, outputs_phase, pipeline
from parcover_env.sim.contract import ScoreState
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
    ``Box(-1, 1, (2,), float32)`` per agent: normalized ``(v, omega)``, fractions of the robot's
    ``max_speed`` (m/s) and ``max_turn_rate`` (rad/s). Values outside [-1, 1] are clipped; NaN/inf,
    a wrong shape, or missing/unknown agents raise ``ActionError`` and leave the state untouched.
    The action is a *command*, not the velocity: with ``robot.drive.model: wheels`` (default) it
    becomes left/right wheel-speed targets (limited to ``drive.wheel_speed_max``), which the wheels
    follow with a first-order lag (``drive.tau``) and bounded acceleration (``drive.accel_max``) at
    the physics rate; from rest, full forward takes a few control steps. ``drive.model: instant``
    (``ideal`` preset) applies the command as the body velocity.

    ## Sonar localization service (opt-in: ``observation.scan.enabled``)
    The action becomes ``Box(-1, 1, (3,))``: ``(v, omega, scan)``. A robot whose ``scan > 0`` starts a
    360-degree sonar scan (Kim, Pearce & Amato's stop-scan-match) and is held still, its ``(v, omega)``
    ignored, for ``ceil(turn / scan.turn_rate / control_dt)`` steps, counting the step that asks: the
    time the real robot turns in place until its ring has read all 72 5-degree directions, ``turn``
    being the largest gap between neighbouring transducers (AmigoBot ring: 72 deg, 21 steps = 2.1 s
    at 0.6 rad/s). ``scan`` is ignored while a scan is under way. At the last step the env simulates
    the robot's scan of the true map (realistic sonar, the episode's generator) and runs the paper's
    localizer on the known map, teammates drawn in at their estimates, inside the ``scan.gate_sigmas``
    region of the robot's *estimate and covariance* (never its true pose). An accepted fix resets the
    estimate and its covariance (``scan.fix_sigma_xy``, ``scan.fix_sigma_heading_deg``) and
    ``fix_age``; a rejected scan changes nothing but that robot's next search region, which widens
    (``scan.miss_inflation``). The ``scanning`` entry is 1 while the scan is under way, ``scan_result`` holds
    the last outcome and ``info[agent]["sonar_fix"]`` this step's (0 on other steps): 1 accepted; 0.5
    held (``scan.confirm_widened``: a fix found only in a widened region waits for a scan from at least
    ``scan.shift_test`` away that agrees: drive on and scan again); -0.5 uninformative (the pose matched
    but the scan does not pin it down, e.g. along a corridor: the region is not widened, a scan from the
    same spot will not pin it either); -1 rejected (the next region is wider); 0 none yet. Off by
    default, so the v1 action and observation spaces (and checkpoints) are unchanged; the ``waypoint``
    policy turns it on (``parcover_env.policies.registry``).
    Module: ``parcover_env.localization.sonar.service``; a test with a known answer: ``tests/envs/test_sonar_fixes.py``.

    How an actor of ``parcover train`` fills ``scan`` (``MarlConfig.scan_head``; ``v``, ``omega`` are a
    TanhNormal with either head: ``tanh(loc)`` under ``torchrl:``, a sample under ``torchrl_sampled:``):

    * ``bernoulli`` (the default with the service): +1 ("scan now") or -1 from a Bernoulli of
      ``p = sigmoid(logit)``; ``torchrl:`` takes its mode, +1 iff ``p > 0.5``, ``torchrl_sampled:`` a draw.
    * ``continuous``: a third TanhNormal component; ``torchrl:`` scans iff ``loc > 0``.

    A learned scan trigger of the ``bernoulli`` head survives evaluation; the ``continuous`` head's
    may live only in the sampling noise (``parcover_env.harness.marl_scan_head``; tests:
    ``tests/policies/test_torchrl_scan_head.py``, the +1 held and scanning, the -1 driving on).

    ## Observation space
    One flat ``Box`` per agent, identical across agents (``env.layout`` names the slices), entries in
    this order:

    OBSERVATION_TABLE

    Generated from the observation spec (``parcover_env.envs.obs_spec.ENTRIES``, one declaration per
    entry); an entry of size 0 in a scenario is absent (the ``sigma_*`` entries without
    ``observation.pose_covariance``; ``sonar`` without ``observation.sonar``).

    The ``sigma_*`` entries (``observation.pose_covariance``, off in the ``ideal`` preset) come from
    the pose covariance the odometry propagates (Chong & Kleeman) and that an absolute fix resets to
    ``observation.fix_sigma_xy`` / ``fix_sigma_heading_deg``: a policy can tell when it is lost.

    Version 2 (``observation.version: 2``, ``parcover_env.parcover_v2``) adds the ``v2`` entries:
    what a robot needs to drive (its target KPOI, a route preview), wait or split (the next TP: the
    group arriving, its branches, the robots on its own branch), follow (the ``k`` nearest
    teammates, ``observation.neighbours``, padded with zeros and ``mate_mask`` 0; its group size)
    and stop (``done_mask``); with ``k`` fixed its size does not depend on the team's.

    ``state()`` is the global state for centralized critics. Version 1: true (x, y, cos, sin) and
    leader flag of every robot, the visited flag of every KPOI, and the elapsed time fraction (its
    length depends on the scenario). Version 2: one shape ``(322,)`` on every map, 16 robot tokens,
    32 KPOI tokens (each ending with its mask; padding is all zeros), then the globals
    (``parcover_env.envs.critic_state``: ``state_tokens(state)`` gives ``(tokens, mask)`` arrays for an
    attention or GNN critic; a scenario with more robots or KPOIs raises ``ConfigError``):

    STATE_TABLE

    ## Rewards
    Per agent, the sum of named terms whose weights come from ``rewards`` in the scenario and which
    are reported in ``info[agent]["reward_<term>"]``: ``kpoi`` (per KPOI newly visited by anyone,
    team reward), ``progress`` (per metre of route-to-go removed, potential-based), ``time`` (per
    step), ``collision`` (per new contact of this agent with a wall or robot). A KPOI is visited
    when a robot's true centre comes within ``kpoi_radius`` of it. Version 2 adds ``own_kpoi`` (per
    KPOI of its own route the agent itself visits: the per-robot reward) and makes ``kpoi`` a small
    team bonus (``parcover_v2``'s weights: ``own_kpoi`` 10, ``kpoi`` 1). A non-zero ``rewards.contact``
    adds ``contact`` (per step the agent is within ``contact_gap`` of touching a wall or robot), a
    non-zero ``rewards.uncertainty`` adds ``uncertainty`` last (per step and metre of the agent's
    ``sigma_major``, its estimate's own uncertainty after this step's fixes: negative, a cost of being
    unsure that Kinect fixes and sonar scans lower).

    Done robots (version 2): once every KPOI of its own route is visited, a robot's ``done_mask``
    entry and ``info[agent]["route_done"]`` are 1; it stays in the world (it can still block and
    collide, and earns the team terms). A MAPPO trainer should death-mask it: its ``active_mask``
    is ``1 - route_done`` (its transitions are left out of the policy and value losses); its
    actions are still applied, so keep acting for it (its policy's action, or a stop).

    ## Episode end
    Terminated when every KPOI is visited; truncated after ``episode.max_steps`` control steps.
    All agents end together. Infos are flat (scalars and arrays, the same keys at reset and at
    every step): the ``reward_<term>`` values and ``metrics/<name>`` entries that are 0 until
    the step that ends the episode (``metrics/ended`` = 1), where they hold the metrics (makespan,
    KPOIs visited, collisions, path lengths, localization error, makespan / (c_max / v_max), ...);
    ``parcover_env.mission.metrics.episode_metrics(info)`` gives them back as a dict.

    ## Infos and analysis
    ``info[agent]`` also holds the per-step estimate error ``pose_error`` (m) and
    ``heading_error`` (rad, absolute). ``env.true_poses()`` and ``env.pose_estimates()`` return
    ``(n_robots, 3)`` arrays (x, y, theta) in agent order, ``env.pose_covariances()`` ``(n_robots, 3, 3)``.

    ## Step and rates
    ``step`` runs the public stepper (``parcover_env.sim.pipeline``), shared with the batched worlds
    and the single-robot env: ``act`` (act, physics, estimator), ``score`` (mission, Alg. 1, rewards,
    metrics), ``observe`` (the spec's entries, every sensor of every world in one call), ``outputs``.
    One step is ``physics.substeps x physics.dt`` seconds (default 5 x 0.02 s); pymunk runs at ``dt``.

    ## Arguments
    ``scenario`` (name, path or Scenario, default ``"office"``), ``render_mode`` (``None``,
    ``"rgb_array"`` or ``"human"``: an OpenCV window, which needs a display and an OpenCV build
    with GUI support), ``overrides`` (nested dict merged over the scenario, e.g.
    ``{"n_robots": 3, "episode": {"max_steps": 500}}``), ``preset`` (``"realistic"`` or
    ``"ideal"``: every error model off), ``max_cycles`` (step limit, like MPE's; default: the
    scenario's ``episode.max_steps``).

    ``env.np_random`` is the episode's ``numpy.random.Generator`` (made by ``reset(seed=...)``).

    ## Version history
    * v2 (0.3.0): observations and rewards to learn from; ``observation.version: 2``, v1 unchanged.
      Observation ``v2`` entries (target KPOI, ``done_mask``, route preview, next TP, group size,
      ``k`` nearest teammates); the ``own_kpoi`` reward term with ``kpoi`` as a team bonus;
      ``info[agent]["route_done"]``; ``state()`` of one fixed shape as robot and KPOI tokens.
    * v1, opt-in ``observation.scan`` (unreleased): the sonar localization service (``scan`` action
      component, ``scanning`` / ``scan_result`` entries, ``info[agent]["sonar_fix"]``; outcomes 1, -1,
      then 0.5 held and -0.5 uninformative, which were -1 before); without it v1 is unchanged.
      A policy of ``parcover train`` fills ``scan`` with +1 / -1 from a Bernoulli head (unreleased;
      the env's ``scan > 0`` rule and action box are unchanged; earlier checkpoints keep their
      continuous ``scan``).
    * v1 (0.2.0): realistic motion and covariance observations (differential-drive dynamics, UMBmark
      odometry, encoder ``v, omega``, ``sigma_*`` entries, realistic Kinect and sonar errors, the
      formation hand-over of promoted followers); flat ``info[agent]["metrics/<name>"]`` and
      ``["reward_<term>"]``; ``human`` render mode; ``max_cycles``; CPU-independent rollouts.
      ``preset="ideal"`` keeps v0's simulation. Details: ``CHANGELOG.md``, 0.2.0.
    * v0 (0.1.0): initial release.
    """

    metadata = {"name": "parcover_v1", "render_modes": ["rgb_array", "human"], "render_fps": 10,
                "is_parallelizable": True}

    def __init__(self, scenario: str | Path | Scenario = "office", render_mode: str | None = None,
                 overrides: dict | None = None, preset: str = "realistic", max_cycles: int | None = None):
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        if max_cycles is not None:
            overrides = deep_merge(overrides or {}, {"episode": {"max_steps": max_cycles}})
        self.scenario = load_scenario(scenario, overrides, preset)
        self.render_mode = render_mode
        s = self.scenario
        self.mission = mission_for(s)
        self.map, self.known_map, self.plan = self.mission.map, self.mission.known_map, self.mission.plan
        self.n_robots = self.plan.r
        self.possible_agents = [f"robot_{i}" for i in range(self.n_robots)]
        self.agents: list[str] = []
        self.sensors = build_sensors(s)
        """The sensor of each ``sensor`` entry of the observation spec (None = off)."""
        self.sonar = self.sensors["sonar"]
        self.kinects = KinectSystem(s, self.map) if s.kinects and s.observation.pose_source == "kinect" else None
        f = s.formation
        self.camera = RelativeCamera(f.camera_fov_deg, f.camera_range, f.camera_range_noise, f.camera_bearing_noise,
                                     f.camera_heading_noise)
        self.layout = ObservationLayout.build(s, self.map.bounds, self.sensors)
        sxy, sth = s.observation.fix_sigma_xy, np.radians(s.observation.fix_sigma_heading_deg)
        self.fix_sources = [KinectFixes(self.kinects, s.robot.markers, np.diag([sxy**2, sxy**2, sth**2]))
                            ] if self.kinects is not None else []
        """The estimator's sources of absolute pose fixes (:class:`~parcover_env.localization.estimator.FixSource`)."""
        self.scanner = SonarFixes(s, self.map.segments, self.n_robots) if s.observation.scan.enabled else None
        """The sonar localization service (``observation.scan``; None = off), the last fix source."""
        if self.scanner is not None:
            self.fix_sources.append(self.scanner)
        self._obs_space = self.layout.space()
        self._act_space = spaces.Box(-1.0, 1.0, (2 if self.scanner is None else 3,), dtype=np.float32)
        self.version = s.observation.version
        """Observation, reward and ``state()`` version (``observation.version``)."""
        self.kpoi_owner = self.plan.kpoi_owner()
        """``(n_kpois,)`` the robot whose route the plan credits with each KPOI (``own_kpoi`` term)."""
        self.features = feature_set(self.version)(self)
        """The version's feature set (:mod:`parcover_env.envs.feature_sets`): its entries' fill functions,
        info values, reward terms and ``state()``."""
        self.terms = paid_terms(self.features.terms, s.rewards)
        """The reward terms, in summing order (``info[agent]["reward_<term>"]``)."""
        self.route_facts = self.features.route_facts
        """Version 2: the routes' static facts the v2 entries and ``state()`` read (``obs_v2.RouteFacts``)."""
        self.state_space = self.features.state_space
        self.score_group = None
        """The score phase's blocks this world's arrays are rows of, when scored with others
        (:class:`~parcover_env.sim.score_phase.ScoreGroup`; None: its own)."""
        self._rng: np.random.Generator | None = None
        self._window: str | None = None

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent: str) -> spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Box:
        return self._act_space

    @property
    def np_random(self) -> np.random.Generator:
        """The episode's random generator (seeded by ``reset(seed=...)``; made unseeded if needed)."""
        if self._rng is None:
            self._rng = np.random.default_rng()
        return self._rng

    @property
    def max_cycles(self) -> int:
        """Step limit of an episode (``episode.max_steps``); settable (takes effect at once)."""
        return self.scenario.episode.max_steps

    @max_cycles.setter
    def max_cycles(self, value: int) -> None:
        import dataclasses

        s = self.scenario
        self.scenario = dataclasses.replace(s, episode=dataclasses.replace(s.episode, max_steps=value))

    # ------------------------------------------------------------------ episode
    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode: ``seed`` None or an integer >= 0, ``options`` None or a dict (none is read
        yet); a bad one raises :class:`~parcover_env.errors.ArgumentError` and changes nothing."""
        seed = check_seed(seed)
        check_options(options)
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        s = self.scenario
        self.agents = list(self.possible_agents)
        self.world = World(self.map, s.robot.radius, s.physics, self.mission.start_poses, s.robot.drive)
        true = self.world.poses()
        self.estimator = PoseEstimator(s, true, self._rng, self.fix_sources)
        self.camera_views: CameraView | None = None
        """The follower cameras' measurements at the last observation of the worlds observed with this
        one, ``(K, N, ...)`` blocks (set by ``stepper.observe``): this world's is row :attr:`camera_index`."""
        self.camera_index = 0
        self.progress = self.mission.tracker()
        self.team = Team(self.plan, s.formation.mode, reach_tol=self.mission.reach_tol)
        self.commands = np.zeros((self.n_robots, 2))
        self.true_velocity = np.zeros((self.n_robots, 2))
        """True world-frame velocity ``(N, 2)``: the last step's displacement / control period (m/s)."""
        self.steps = 0
        self.score_state = ScoreState.start(self.progress.remaining(true[:, :2]))
        """What the stepper's score phase carries over between steps (route to go, contacts so far)."""
        self.metrics = EpisodeMetrics(len(s.kpois), self.n_robots, self.plan.c_max, s.robot.max_speed,
                                      path_lengths=[0.0] * self.n_robots)
        self.trails = [[p[:2].copy()] for p in true]
        self.progress.update(true[:, :2], self.estimate[:, :2], 0.0)
        update_team(self.team, self.kinects, self.estimate, self.progress.plan_progress, self.camera_view)
        obs = self._as_dict(pipeline.observe([self], true[None])[0])
        zeros = [[0.0] * self.n_robots]
        return obs, outputs_phase.infos([self], true[None], [zeros] * len(self.terms), [False])[0]

    def step(self, actions: dict[str, Any]):
        if not self.agents:  # checked here, not in entry_checks: a step runs as few modules as it can
            require_episode(self, "step()")
            raise CallOrderError("step() called on a finished episode; call reset() first")
        obs, out = pipeline.step([self], [actions])
        return self._as_dict(obs[0]), *outputs_phase.agent_dicts(self.possible_agents, out)

    def _as_dict(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        return dict(zip(self.possible_agents, obs, strict=True))  # all agents live or end together

    def act(self, actions: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
        """Stepper part 1a (:func:`parcover_env.sim.act_phase.act` of this world alone): act,
        integrate the physics, update the pose estimator (odometry, fixes).
        Returns the true poses ``(N, 3)`` before and after the step."""
        acted = act_phase.act([self], [actions])
        return acted.before[0], acted.true[0]

    @property
    def camera_view(self) -> CameraView | None:
        """The follower cameras' measurements at the last observation (None before the first)."""
        views = getattr(self, "camera_views", None)
        return None if views is None else views.select(self.camera_index)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["score_group"] = None  # the blocks of the worlds scored with this one: a copy holds its own arrays
        views = state.get("camera_views")
        if views is not None and len(views.predecessor) > 1:  # a copy keeps its own world's measurements only
            k = state["camera_index"]
            state["camera_views"], state["camera_index"] = views.select(slice(k, k + 1)), 0
        return state

    # ------------------------------------------------------------------ extras
    @property
    def estimate(self) -> np.ndarray:
        """The pose estimates ``(n_robots, 3)`` (the estimator's; not a copy)."""
        return self.estimator.estimate

    def localization_entries(self) -> dict[str, np.ndarray]:
        """The ``scan`` entries of the observation spec, ``{name: (n_robots,)}`` (empty when
        ``observation.scan`` is off): ``scanning`` and ``scan_result``."""
        if self.scanner is None:
            return {}
        return {"scanning": self.scanner.scanning.astype(float), "scan_result": self.scanner.result}

    @property
    def fix_age(self) -> np.ndarray:
        """Seconds since each robot's last absolute pose fix ``(n_robots,)``."""
        return self.estimator.fix_age

    @property
    def odometry(self):
        """The estimator's wheel odometry (:class:`~parcover_env.sensors.odometry.Odometry`)."""
        return self.estimator.odometry

    def true_poses(self) -> np.ndarray:
        """Ground-truth poses ``(n_robots, 3)`` (x, y m; theta rad in (-pi, pi]) in agent order."""
        require_episode(self, "true_poses()")
        return self.world.poses()

    def pose_estimates(self) -> np.ndarray:
        """The robots' pose estimates ``(n_robots, 3)`` (the observations' x, y, theta), agent order."""
        require_episode(self, "pose_estimates()")
        return self.estimate.copy()

    def pose_covariances(self) -> np.ndarray:
        """Covariances ``(n_robots, 3, 3)`` of the pose estimates (m^2, m rad, rad^2), agent order."""
        require_episode(self, "pose_covariances()")
        return self.estimator.covariance.copy()

    def route_done(self) -> np.ndarray:
        """Version 2: ``(N,)`` bool, every KPOI of each robot's own route visited (its ``done_mask``)."""
        require_episode(self, "route_done()")
        return self.features.route_done(self)

    def state(self) -> np.ndarray:
        """The global state for a centralized critic (see the class docstring; its layout is the version's)."""
        require_episode(self, "state()")
        return self.features.state(self)

    def kinect_frames(self) -> dict:
        """Depth + IR frames (``KinectFrame``) of every overhead Kinect: in ``observation.kinect:
        frames`` mode those of the last Kinect tick, otherwise rendered now from a generator seeded
        by the step count (calling this never changes the episode)."""
        require_episode(self, "kinect_frames()")
        if self.kinects is None:
            return {}
        if self.scenario.observation.kinect == "frames" and self.kinects.frames:
            return dict(self.kinects.frames)
        markers = self.team.leader & self.scenario.robot.markers
        return self.kinects.render_frames(self.world.poses(), markers, seed=self.steps)

    def render(self) -> np.ndarray | None:
        """``rgb_array``: the top-down frame (H, W, 3) uint8; ``human``: show it in a window, None."""
        if self.render_mode is None:
            return None
        require_episode(self, "render()")
        from parcover_env.viz.render import render_frame, show_frame

        frame = render_frame(self)
        if self.render_mode == "human":
            self._window = show_frame(frame, f"parcover {self.scenario.name}", 1000 // self.metadata["render_fps"])
            return None
        return frame

    def close(self) -> None:
        if self._window is not None:
            from parcover_env.viz.render import close_window

            close_window(self._window)
            self._window = None


if ParallelCoverageEnv.__doc__:  # the observation table, generated from the spec (absent under python -OO)
    ParallelCoverageEnv.__doc__ = ParallelCoverageEnv.__doc__.replace(
        "OBSERVATION_TABLE", markdown_table().replace("\n", "\n    ")).replace(
        "STATE_TABLE", critic_state.markdown_table().replace("\n", "\n    "))

