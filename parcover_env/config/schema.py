"""Scenario schema: frozen typed dataclasses, one per concern, each field documented with its unit.

Per-field checks live in ``__post_init__``; checks that need the map's geometry live in
:mod:`parcover_env.scenarios.validation` and run when a scenario is loaded.

Units: metres, seconds, radians per second for rates. Angles typed by people in YAML carry a
``_deg`` suffix (degrees) and are converted where they are used.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any, Literal

from parcover_env.config.checks import check as _check
from parcover_env.config.checks import positive as _positive
from parcover_env.config.localization import KinectTrackingConfig
from parcover_env.config.robot import DriveConfig, KinectConfig, OdometryConfig, Point, RobotConfig, SonarConfig
from parcover_env.errors import ConfigError

Polygon = tuple[Point, ...]
Segment = tuple[Point, Point]

__all__ = [
    "ConfigError", "MapConfig", "Pose", "SonarConfig", "DriveConfig", "OdometryConfig", "RobotConfig",
    "KinectConfig", "PhysicsConfig", "EpisodeConfig", "RewardConfig", "ObservationConfig", "ScanConfig",
    "FormationConfig", "PlannerConfig", "KinectTrackingConfig", "Scenario",
    "Point", "Polygon", "Segment", "MAX_ROBOTS",
]

MAX_ROBOTS = 256
"""Most robots a team may have (``n_robots``; also the planner's ``n_robots`` bound)."""


MAX_RASTER_CELLS = 4e6
"""The planner rasterizes the map at ``planner.resolution``: at most this many cells (memory, time)."""




@dataclass(frozen=True)
class MapConfig:
    """The indoor map. Origin at the bottom-left corner; x right, y up (m)."""

    size: tuple[float, float]
    """Width and height of the map's bounding box (m)."""
    boundary: Polygon | None = None
    """Outline of the floor (outer wall); defaults to the ``size`` rectangle."""
    walls: tuple[Segment, ...] = ()
    """Thin walls as segments ((x1, y1), (x2, y2)), thickened by ``wall_thickness``."""
    wall_thickness: float = 0.1
    obstacles: tuple[Polygon, ...] = ()
    """Obstacles known to the map (polygons)."""
    unknown_obstacles: tuple[Polygon, ...] = ()
    """Obstacles present in the world but absent from the map the expert and localizers get."""

    def __post_init__(self) -> None:
        _positive(self, "wall_thickness")
        for i, s in enumerate(self.size):
            _check(s > 0, f"size[{i}]", f"must be > 0, got {s}")
        _check(max(self.size) <= 1000, "size", f"maps larger than 1 km are not supported, got {self.size}")
        for i, (a, b) in enumerate(self.walls):
            _check(a != b, f"walls[{i}]", "segment has zero length")
        w, h = self.size
        for name in ("boundary", "obstacles", "unknown_obstacles", "walls"):
            polys = [self.boundary] if name == "boundary" else getattr(self, name)
            for i, poly in enumerate(polys):
                if poly is None:
                    continue
                key = name if name == "boundary" else f"{name}[{i}]"
                if name != "walls":
                    _check(len(poly) >= 3, key, f"a polygon needs >= 3 vertices, got {len(poly)}")
                for x, y in poly:
                    _check(-1e-9 <= x <= w + 1e-9 and -1e-9 <= y <= h + 1e-9, key,
                           f"vertex ({x}, {y}) lies outside the map box [0, {w}] x [0, {h}] (map.size)")


@dataclass(frozen=True)
class Pose:
    x: float
    y: float
    theta_deg: float = 0.0

    @property
    def theta(self) -> float:
        return math.radians(self.theta_deg)


@dataclass(frozen=True)
class PhysicsConfig:
    """Physics integration step and how many of them make one control (decision) step."""

    dt: float = 0.02
    substeps: int = 5
    collision_slop: float = 0.001

    def __post_init__(self) -> None:
        _positive(self, "dt", "substeps")
        _check(self.dt <= 0.1, "dt", f"physics steps above 0.1 s are unstable, got {self.dt}")
        _check(self.substeps <= 1000, "substeps", f"must be <= 1000, got {self.substeps}")
        _check(0 <= self.collision_slop <= 0.01, "collision_slop", "must be in [0, 0.01] m")

    @functools.cached_property
    def control_dt(self) -> float:
        """One control step, ``dt * substeps`` (s); computed once (the step reads it several times)."""
        return self.dt * self.substeps


@dataclass(frozen=True)
class EpisodeConfig:
    max_steps: int = 1000

    def __post_init__(self) -> None:
        _positive(self, "max_steps")


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the named reward terms (see the env's docstring)."""

    kpoi: float = 10.0
    """Per KPOI visited, to every agent (team reward)."""
    progress: float = 1.0
    """Per metre of route length left that the agent removed this step (potential-based; the
    route length left is the straight distance from the robot's true position to its goal point
    on its route plus the route's length from that point to its end, so driving back costs it)."""
    time: float = -0.01
    """Per step, to every agent."""
    collision: float = -1.0
    """Per new contact of this agent with a wall or another robot."""
    own_kpoi: float = 0.0
    """Per KPOI of the agent's own route (the plan credits it with that KPOI) that the agent itself
    visits: the per-robot KPOI reward (``parcover_v2`` sets 10, with ``kpoi`` a team bonus of 1;
    0 keeps v1's rewards). A KPOI of another robot's route visited by this agent pays only ``kpoi``."""
    contact: float = 0.0
    """Per step that this agent is touching a wall or another robot (its true centre within
    ``contact_gap`` of touching), however long the contact lasts (``collision`` pays only its start).
    0 (default): no ``contact`` term at all (the env's terms, infos and rollouts as without it)."""
    contact_gap: float = 0.02
    """Gap (m) under which the ``contact`` term counts a robot as touching a wall or robot."""
    uncertainty: float = 0.0
    """Per step and metre of the agent's position uncertainty: the major axis (1 sigma) of its
    estimate's own covariance ellipse after this step's fixes (the observation's ``sigma_major``; the
    estimate's belief, never its true error). Negative: a cost of being unsure, which Kinect fixes and
    sonar scans (``observation.scan``) lower. 0 (default): no ``uncertainty`` term at all."""

    def __post_init__(self) -> None:
        _positive(self, "contact_gap")


@dataclass(frozen=True)
class ScanConfig:
    """The env's sonar localization service (Kim, Pearce & Amato's stop-scan-match), opt-in.

    With ``enabled`` the action gains a third component ``scan``: a robot whose ``scan > 0`` starts
    a 360-degree sonar scan and is held still (commands zeroed) for the scan's duration, the time the
    real robot takes to turn in place at ``turn_rate`` until its ring has read all 72 5-degree
    directions (through the largest gap between neighbouring transducers). At the scan's
    last step the env simulates that robot's scan of the true map (realistic sonar model, the
    episode's generator) and runs the paper's localizer on the known map, teammates drawn in at
    their estimates, inside the ``gate_sigmas`` ellipse of the robot's estimate and covariance (never
    the true pose). A fix is accepted when the localizer succeeds (or the scan matches on the readings
    no teammate explains, ``mask_sigmas``) inside that gate. An accepted fix resets the estimate to
    the fix and the covariance to ``fix_sigma_xy`` / ``fix_sigma_heading_deg``, provided the scan pins
    the pose down (``shift_test``) and, when found only in a region widened by earlier rejections and
    ``confirm_widened`` is on, a second scan agrees with it; a rejected one changes nothing but the next search
    region of that robot (``miss_inflation``)."""

    enabled: bool = False
    """Add the ``scan`` action component and the ``scanning`` / ``scan_result`` observation entries."""
    turn_rate: float = 0.6
    """Turn rate of the real robot during a scan (rad/s; capped at ``robot.max_turn_rate``; the
    scripted expert's ``sonar_fix.scan_rate``): a scan lasts ``ceil(turn / turn_rate / control_dt)``
    control steps, ``turn`` the largest gap between neighbouring transducers (AmigoBot ring: 72 deg,
    21 steps = 2.1 s at 0.6 rad/s and 0.1 s; an evenly spaced ring of n: 360 / n deg)."""
    gate_sigmas: float = 3.0
    """The localizer searches, and a fix is accepted only inside, this many standard deviations of
    the estimate's position covariance widened by ``gate_distance`` (Mahalanobis distance) (-)."""
    gate_distance: float = 0.15
    """Floor of that region (m): the covariance is widened by (``gate_distance`` / ``gate_sigmas``)^2
    in every direction, so a fresh estimate's tiny covariance still admits the localizer's error."""
    gate_heading_deg: float = 30.0
    """A fix is accepted only within this of the heading estimate plus ``gate_sigmas`` heading sigmas (deg) ..."""
    gate_heading_max_deg: float = 40.0
    """... at most this (deg; below 90): rooms are nearly symmetric, and a scan often matches the map
    turned by 90 or 180 degrees about a nearby point; the heading sigma grows with each rejected
    scan (``miss_inflation``), and an uncapped gate would soon admit those turned matches."""
    fix_sigma_xy: float = 0.05
    """Position standard deviation of an accepted sonar fix along x and y (m): the covariance the
    estimate restarts from (the localizer's error on the shipped maps, ``benchmarks/sonar_localization.py``)."""
    fix_sigma_heading_deg: float = 2.0
    """Heading standard deviation of an accepted sonar fix (deg)."""
    mask_sigmas: float = 2.0
    """Teammates are not in the known map: a localized pose whose scan error is too large is still
    accepted when the scan matches on the readings no teammate can explain (a reading shorter than
    the known map's that ends within radius + this many position sigmas of a teammate's estimate is
    left out) (-) ..."""
    min_unmasked_share: float = 0.5
    """... provided at least this share of the readings is left (-)."""
    miss_inflation: float = 2.0
    """Each rejected scan (unless rejected only by ``shift_test``: an uninformative scan says nothing
    about the region) widens the robot's next search region and gate: the standard deviations
    are multiplied by this (-), until an accepted fix. Contacts push robots unseen by the encoders; a
    robot pushed outside its covariance is otherwise never found inside its search region."""
    max_inflation: float = 8.0
    """Largest total factor of ``miss_inflation`` (-): the search region stays bounded."""
    shift_test: float = 0.2
    """A fix is accepted only if the scan pins the pose down: from the pose shifted by this distance
    (m) in any of 8 directions, the scan must match the known map worse by at least
    ``min_shift_increase`` (:mod:`~parcover_env.localization.sonar.pin_down`; the localizer's
    clipped, trimmed scan error, the one that accepts the fix). A scan of open space (few echoes:
    the trim drops them all) or along a straight corridor matches about as well shifted, and the
    localizer's pose is then a guess along the free direction. 0 switches the test off."""
    min_shift_increase: float = 0.003
    """Smallest increase of the mean clipped scan error under that shift (m); the scripted expert's
    own loop's value (``expert.sonar_fix.min_shift_increase``, measured there on generated maps)."""
    confirm_widened: bool = False
    """A fix found only in a region widened by ``miss_inflation`` (outside the gate of the estimate's
    own covariance) needs a second scan that agrees with it: it is held (the scan reports ``scan_result``
    0.5, the region is not widened further) and applied when a later scan, taken with the estimate at
    least ``shift_test`` from where it was at the held scan, finds a fix inside the gate of a fresh fix
    (``fix_sigma_xy``, ``fix_sigma_heading_deg``, ``gate_sigmas``, ``gate_distance``) around the held fix
    carried along by the estimate's motion; a disagreeing fix from there is held in its place, a scan
    from closer changes nothing (a look-alike match repeats from the same spot). A widened region
    several metres across holds look-alike places of the map; a fix within the estimate's own gate is
    applied at once. False (default) applies every fix found in the region. With it on, a pose found
    outside the estimate's own gate gives way to a match inside that gate if the scan has one (the far
    one is a look-alike). Measured with the scripted expert driving on before its next scan
    (``expert.sonar_fix.relocate_distance`` 0.5 m): generated seeds 0-199 199 / 200, off 195 / 200;
    200-299 98 / 100, off 97 / 100 (``docs/lab/expert_benchmark.md``, 2026-11-26). The registered expert's
    env turns it on, except for the sonar navigator (``localization: sonar``)."""

    def __post_init__(self) -> None:
        _check(self.shift_test >= 0, "shift_test", f"must be >= 0, got {self.shift_test}")
        _check(self.min_shift_increase >= 0, "min_shift_increase", f"must be >= 0, got {self.min_shift_increase}")
        _check(self.miss_inflation >= 1, "miss_inflation", f"must be >= 1, got {self.miss_inflation}")
        _check(self.max_inflation >= 1, "max_inflation", f"must be >= 1, got {self.max_inflation}")
        _check(self.mask_sigmas >= 0, "mask_sigmas", f"must be >= 0, got {self.mask_sigmas}")
        _check(0 < self.min_unmasked_share <= 1, "min_unmasked_share",
               f"must be in (0, 1], got {self.min_unmasked_share}")
        _positive(self, "turn_rate", "gate_sigmas", "gate_heading_deg", "fix_sigma_xy", "fix_sigma_heading_deg")
        _check(self.gate_heading_deg <= self.gate_heading_max_deg < 90, "gate_heading_max_deg",
               f"must be >= gate_heading_deg ({self.gate_heading_deg}) and < 90, got {self.gate_heading_max_deg}")
        _check(self.gate_distance >= 0, "gate_distance", f"must be >= 0, got {self.gate_distance}")


@dataclass(frozen=True)
class ObservationConfig:
    pose_source: Literal["odometry", "kinect", "ground_truth"] = "kinect"
    """Where the pose in the observation comes from: ``kinect`` = odometry corrected by Kinect
    fixes for leaders inside a footprint (the paper); ``odometry`` = dead reckoning only."""
    kinect: Literal["estimate", "frames"] = "estimate"
    """``estimate``: pipeline poses only; ``frames``: raw frames via ``env.kinect_frames()``."""
    sonar: bool = True
    pose_covariance: bool = True
    """Observe the pose covariance (uncertainty ellipse axes and heading sigma); the ``ideal``
    preset turns it off (its odometry has no modelled uncertainty)."""
    fix_sigma_xy: float = 0.03
    """Standard deviation of an absolute (Kinect) fix along x and y (m): the covariance the pose
    estimate restarts from after a fix."""
    fix_sigma_heading_deg: float = 2.0
    """Standard deviation of an absolute fix's heading (degrees)."""
    version: Literal[1, 2] = 1
    """Observation and ``state()`` version: 1 = ``parcover_v1``'s; 2 = ``parcover_v2``'s (adds the
    own-KPOI, route preview, next-TP, nearest-teammate, group-size and done-mask entries; the
    fixed-shape token ``state()``)."""
    neighbours: int = 4
    """Version 2: teammates (k nearest by estimated distance) each robot observes; fewer teammates
    are padded with zeros and mask 0."""
    scan: ScanConfig = field(default_factory=ScanConfig)
    """The sonar localization service: the ``scan`` action (opt-in, :class:`ScanConfig`)."""

    def __post_init__(self) -> None:
        _check(self.version in (1, 2), "version", f"must be 1 or 2, got {self.version!r}")
        _check(isinstance(self.neighbours, int) and 0 <= self.neighbours <= 15, "neighbours",
               f"must be an integer in [0, 15], got {self.neighbours!r}")
        _check(self.fix_sigma_xy >= 0, "fix_sigma_xy", f"noise must be >= 0, got {self.fix_sigma_xy}")
        _check(self.fix_sigma_heading_deg >= 0, "fix_sigma_heading_deg",
               f"noise must be >= 0, got {self.fix_sigma_heading_deg}")


@dataclass(frozen=True)
class FormationConfig:
    """Leader-follower column formation (l-psi control, Min et al. eq. 3)."""

    spacing: float = 0.5
    """Desired separation l_d between consecutive robots (m)."""
    bearing_deg: float = 180.0
    """Desired bearing psi_d of a follower seen from its predecessor (180 = behind)."""
    offset: float = 0.2
    """Control point offset d ahead of the follower's axle (m)."""
    gains: tuple[float, float] = (1.0, 0.7)
    """(a1, a2) of the l-psi law."""
    mode: Literal["formation", "individual"] = "formation"
    """``individual``: no formations, every robot is localized and messaged on its own."""
    camera_fov_deg: float = 120.0
    """Field of view of the follower's onboard camera that measures the robot ahead."""
    camera_range: float = 2.5
    """Max range of that camera (m)."""
    camera_range_noise: float = 0.01
    """Range sigma of that camera per metre of distance (-): a marker camera degrades with distance."""
    camera_bearing_noise: float = 0.01
    """Bearing sigma of that camera (rad)."""
    camera_heading_noise: float = 0.03
    """Sigma of the measured relative heading of the robot ahead (rad)."""

    def __post_init__(self) -> None:
        _positive(self, "spacing", "offset", "camera_fov_deg", "camera_range")
        for name in ("camera_range_noise", "camera_bearing_noise", "camera_heading_noise"):
            value = getattr(self, name)
            _check(0.0 <= value <= 0.5, name, f"must be in [0, 0.5], got {value}")
        _check(all(g > 0 for g in self.gains), "gains", "must be > 0")


@dataclass(frozen=True)
class PlannerConfig:
    roadmap: Literal["medial_axis", "grid"] = "medial_axis"
    resolution: float = 0.05
    """Grid cell size used to build the roadmap (m)."""
    tp_merge_tol: float = 0.1
    """Turning positions reached within this distance (m, along the paths) after another one merge
    into it: one multi-way TP (Min et al. Fig. 2, Alg. 1 step 3a) instead of a cascade of two-way splits
    where the roadmap forks at several nearby points. About half a corridor width suits hub rooms."""

    def __post_init__(self) -> None:
        _check(0.005 <= self.resolution <= 1.0, "resolution", "must be in [0.005, 1.0] m")
        _check(0.0 <= self.tp_merge_tol <= 5.0, "tp_merge_tol", f"must be in [0, 5] m, got {self.tp_merge_tol}")


@dataclass(frozen=True)
class Scenario:
    """A whole mission: map, team, sensors, rates, limits and reward weights."""

    name: str
    map: MapConfig
    start: Pose
    kpois: tuple[Point, ...]
    description: str = ""
    kpoi_radius: float = 0.25
    """A KPOI is visited when a robot centre comes within this distance (m)."""
    n_robots: int | Literal["auto"] = "auto"
    """Team size; ``auto`` = the PPCP planner's optimal r."""
    start_queue: tuple[Point, ...] = ()
    """Polyline from the start backwards along which the team lines up in column order, one robot
    every ``formation.spacing`` (m). Empty: straight back from the start, then side by side."""
    robot: RobotConfig = field(default_factory=RobotConfig)
    kinects: tuple[KinectConfig, ...] = ()
    formation: FormationConfig = field(default_factory=FormationConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    localization: Literal["kinect", "sonar", "both"] = "kinect"
    sonar_localizer: dict[str, Any] = field(default_factory=dict, hash=False)
    """The sonar localizer's YAML section, kept as read (used by the env's ``observation.scan``
    service and the experts); its owner validates it
    (:func:`parcover_env.localization.sonar.config.sonar_localizer_config`)."""
    kinect_tracking: KinectTrackingConfig = field(default_factory=KinectTrackingConfig)
    """Gate and fusion radius of the Kinect leader tracker (Min et al.)."""
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
    episode: EpisodeConfig = field(default_factory=EpisodeConfig)
    rewards: RewardConfig = field(default_factory=RewardConfig)
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    expert: dict[str, Any] = field(default_factory=dict, hash=False)
    """The scripted experts' YAML section, kept as read: the env never reads it; its owner validates
    it (:func:`parcover_env.expert.config.expert_config`)."""
    source: str = field(default="<dict>", compare=False, metadata={"internal": True})

    def __post_init__(self) -> None:
        _check(len(self.kpois) >= 1, "kpois", "at least one KPOI is required")
        _check(len(self.kpois) <= 10000, "kpois", f"at most 10000 KPOIs, got {len(self.kpois)}")
        _positive(self, "kpoi_radius")
        if self.n_robots != "auto":
            _check(1 <= self.n_robots <= MAX_ROBOTS, "n_robots",
                   f"must be in [1, {MAX_ROBOTS}] or 'auto', got {self.n_robots}")
        if self.n_robots != 1:
            f = self.formation
            _check(f.spacing - f.offset >= 2 * self.robot.radius - 1e-9, "formation.spacing",
                   f"a follower steering its control point {f.offset} m ahead to {f.spacing} m behind the robot "
                   f"ahead comes within {f.spacing - f.offset:.3f} m of it: less than two radii "
                   f"({2 * self.robot.radius} m); increase spacing or reduce offset")
        for i, k in enumerate(self.kinects):
            _check(k.height > self.robot.height + 0.1, f"kinects[{i}].height",
                   f"the Kinect must hang above the robots' tops ({self.robot.height} m)")
        names = [k.name for k in self.kinects]
        _check(len(set(names)) == len(names), "kinects", f"Kinect names must be unique, got {names}")
        step = self.robot.max_speed * self.physics.dt
        _check(step < 0.5 * min(self.robot.radius, self.map.wall_thickness), "physics.dt",
               f"a robot moves {step:.3f} m per physics step: more than half the robot radius or wall "
               "thickness risks tunnelling; lower physics.dt")
        cells = (self.map.size[0] / self.planner.resolution) * (self.map.size[1] / self.planner.resolution)
        if cells > MAX_RASTER_CELLS:
            fit = (self.map.size[0] * self.map.size[1] / MAX_RASTER_CELLS) ** 0.5
            raise ConfigError("", "planner.resolution", f"the {self.map.size[0]} x {self.map.size[1]} m map needs "
                              f"{cells:.3g} roadmap cells at {self.planner.resolution} m (max {MAX_RASTER_CELLS:.0e}); "
                              f"use a resolution >= {fit:.3f} m")

    @property
    def queue(self) -> tuple[Point, ...]:
        """The start queue polyline, beginning at the start."""
        return ((self.start.x, self.start.y), *self.start_queue) if self.start_queue else ()

    @property
    def n_robots_fixed(self) -> int | None:
        return None if self.n_robots == "auto" else int(self.n_robots)
