"""The robot and its sensors: wheels, odometry, sonar ring, and the overhead Kinects it is seen by.

Units: metres, seconds, radians per second for rates; angles typed by people carry a ``_deg`` suffix.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from parcover_env.config.checks import check as _check
from parcover_env.config.checks import positive as _positive

Point = tuple[float, float]

__all__ = ["SonarConfig", "LidarConfig", "DriveConfig", "OdometryConfig", "RobotConfig", "KinectConfig"]


@dataclass(frozen=True)
class SonarConfig:
    """Sonar ring (Kim, Pearce & Amato: AmigoBot). The default is the realistic model: a cone of ``cone_deg``
    whose walls echo only near normal incidence, multipath, retro-reflecting concave corners,
    echoes from robots, cross-talk between rings and readings lost below ``range_min``.
    ``model: ray`` is one ideal ray per beam (the ``ideal`` preset). ``model: fast`` is the cheap
    option for training: one ray per beam along its axis (walls and the other robots of its world),
    with the realistic model's range noise, quantization, drops below ``range_min`` and garbage, plus
    random dropouts at ``dropout_prob``; it has no cone, no specular incidence limit, no multipath,
    no corner echoes and no cross-talk (``benchmarks/sonar_realism.py`` measures how far it reads
    from the specular model)."""

    layout: Literal["ring", "amigobot"] = "ring"
    n_beams: int = 16
    """Number of evenly spaced beams for ``layout: ring`` (ignored for ``amigobot``: 8)."""
    range_min: float = 0.15
    """Nearest measurable range (m): the transducer still rings while a nearer echo returns."""
    range_max: float = 2.54
    """Farthest range (m); a beam with no echo reads this (Kim, Pearce & Amato: 2.54 m = 'too far')."""
    model: Literal["ray", "specular", "fast"] = "specular"
    """``specular``: a cone of sub-rays with the specular physics below; ``ray``: one ideal ray
    (with cross-talk); ``fast``: one ray, noise and dropouts, no cross-talk (see above)."""
    cone_deg: float = 30.0
    """Full opening angle of a beam (deg), sampled by sub-rays (specular model)."""
    incidence_max_deg: float = 20.0
    """Specular model: a wall echoes only if the beam meets it within this angle of its normal (deg)."""
    multipath: bool = True
    """Specular model: a sub-ray reflected away by an oblique wall is followed to the next surface;
    if that one returns it, the reading is the two-bounce length (too long). False: lost."""
    crosstalk_prob: float = 0.1
    """Probability that a beam facing another robot's transducer that fires at it (each inside the
    other's cone, in line of sight) reads that robot's ping instead: half the distance between
    them, as time of flight is halved for a round trip. 0 = rings never hear each other."""
    below_min: Literal["drop", "clip"] = "drop"
    """An echo nearer than ``range_min``: ``drop`` = lost (reads ``range_max``), ``clip`` = reads
    ``range_min``."""
    noise_std: float = 0.01
    noise_rel: float = 0.01
    """Range noise sigma = noise_std + noise_rel * range (m)."""
    quantization: float = 0.01
    """Range resolution of a reading (m); 0 = continuous."""
    scan_step_deg: float = 5.0
    """Angular step of a 360-degree scan (72 readings at 5 degrees)."""
    garbage_rate: float = 0.0
    """Fault injection: probability that a reading is replaced by a uniform random range."""
    dropout_prob: float = 0.0
    """``fast`` model only: probability (-) that an echo is lost and reads ``range_max`` (a stand-in
    for the echoes the specular model loses at oblique walls, which the fast model does not trace).
    Other models ignore it."""

    def __post_init__(self) -> None:
        _positive(self, "n_beams", "range_max", "cone_deg", "scan_step_deg")
        _check(0 <= self.range_min < self.range_max, "range_min", "must satisfy 0 <= range_min < range_max")
        _check(self.noise_std >= 0 and self.noise_rel >= 0, "noise_std", "noise must be >= 0")
        _check(self.quantization >= 0, "quantization", "must be >= 0")
        _check(0 <= self.garbage_rate <= 1, "garbage_rate", "must be in [0, 1]")
        _check(0 <= self.dropout_prob <= 1, "dropout_prob", f"must be in [0, 1], got {self.dropout_prob}")
        _check(0 <= self.crosstalk_prob <= 1, "crosstalk_prob", f"must be in [0, 1], got {self.crosstalk_prob}")
        _check(0 < self.incidence_max_deg <= 90, "incidence_max_deg", "must be in (0, 90]")
        _check(self.cone_deg < 180, "cone_deg", f"must be < 180, got {self.cone_deg}")


@dataclass(frozen=True)
class LidarConfig:
    """A 2-D scanning lidar on the robot's centre (VMAS-like): ``n_rays`` rays evenly over 360
    degrees, ray ``i`` at ``360 i / n_rays`` degrees from the heading; walls and the other robots
    (discs) reflect; a ray with no hit within ``range_max`` reads ``range_max``. Off by default;
    ``enabled: true`` adds the ``lidar`` entry to the observation."""

    enabled: bool = False
    """Observe the lidar (the ``lidar`` observation entry, ``n_rays`` columns)."""
    n_rays: int = 16
    """Rays per scan, evenly spaced over 360 degrees."""
    range_max: float = 3.0
    """Farthest range (m), read by a ray that hits nothing nearer."""
    noise_std: float = 0.01
    """Gaussian range noise sigma (m) of a ray that hits; the reading is clipped to [0, range_max]."""

    def __post_init__(self) -> None:
        _positive(self, "n_rays", "range_max")
        _check(self.noise_std >= 0, "noise_std", f"noise must be >= 0, got {self.noise_std}")


@dataclass(frozen=True)
class DriveConfig:
    """Differential-drive dynamics: normalized actions -> wheel-speed targets -> wheel speeds.

    The action (v, omega) becomes left/right wheel ground-speed targets
    ``v -+ omega * wheel_base / 2``; if a target exceeds ``wheel_speed_max`` both are scaled down
    by the same factor (the path's curvature is kept). Each wheel then follows its target through
    a first-order lag of time constant ``tau`` whose rate of change is bounded by ``accel_max``,
    integrated exactly at the physics rate ``physics.dt``.

    Figures: Kim, Pearce & Amato's AmigoBot. ARIA's robot parameter file for it (``params/amigo.p``, ActivMedia /
    MobileRobots) gives ``MaxVelocity 1000`` mm/s and ``DiffConvFactor 0.011`` (rotation rate =
    (v_R - v_L) / 2 * DiffConvFactor, wheel speeds in mm/s), i.e. an effective wheel base of
    2 / 0.011 mm = 0.18 m. The AmigoBot manual (AmigoBot Technical Manual v1.3, 2002) describes a
    trapezoidal velocity profile with FLASH-configured accelerations but the parameter file leaves
    them to the firmware (0 = FLASH value); ``accel_max`` and ``tau`` are therefore chosen, not
    read off a sheet: with them a robot at rest commanded to full forward (0.3 m/s) reaches 33 %
    of it after one 0.1 s control step and 90 % after 0.4 s (``tests/world/test_drive.py``,
    ``benchmarks/odometry_drift.py``).
    """

    model: Literal["wheels", "instant"] = "wheels"
    """``wheels``: wheel-speed limits, lag and bounded acceleration (realistic); ``instant``: the
    commanded (v, omega) is the body velocity at the next physics step (the ``ideal`` preset)."""
    wheel_base: float = 0.18
    """Distance between the wheels' contact points, the effective wheel base b (m)."""
    wheel_speed_max: float = 1.0
    """Max ground speed of each wheel (m/s); must allow ``robot.max_speed``."""
    accel_max: float = 1.0
    """Max rate of change of each wheel's ground speed (m/s^2)."""
    tau: float = 0.1
    """Time constant of the first-order lag from wheel-speed target to wheel speed (s)."""

    def __post_init__(self) -> None:
        _positive(self, "wheel_base", "wheel_speed_max", "accel_max", "tau")
        _check(self.tau <= 10.0, "tau", f"a lag above 10 s leaves the robot practically unable to move, got {self.tau}")


@dataclass(frozen=True)
class OdometryConfig:
    """Wheel odometry and its errors.

    ``model: wheels`` (realistic) integrates the wheel encoders, i.e. the wheel motion the drive
    produced, never the body's true motion: pushes from contacts go unseen. Its errors follow
    Borenstein & Feng's UMBmark and Chong & Kleeman (1997):

    * systematic, drawn per robot per episode from the episode RNG: wheel-diameter ratio
      E_d = D_R / D_L ~ 1 + N(0, ``diameter_ratio_std``), mean-diameter (scale) error
      ~ N(0, ``scale_std``) and effective wheel-base ratio E_b = b_actual / b_nominal ~
      1 + N(0, ``wheelbase_std``). The encoders convert ticks with the nominal diameter and wheel
      base: a straight drive with E_d > 1 is believed to curve clockwise (the robot really drifts
      left of its estimate) and every turn is believed E_b times larger than it is;
    * random: each wheel's distance error has variance ``wheel_variance`` x |distance| (m^2);
    * slip: each wheel's encoder over-reads its ground distance by a fraction
      |N(0, 1)| x (``slip_accel`` x |wheel acceleration| + ``slip_turn`` x |turn rate|).

    The pose covariance is propagated per step with Chong & Kleeman's wheel-increment Jacobians,
    from a per-wheel variance ``covariance_wheel_variance`` x |distance| that also covers the
    systematic errors the robot cannot know, and reset to the fix's covariance at absolute fixes.

    Calibration: UMBmark's typical uncalibrated E_d of 1.001-1.01 and E_b of 1-2 % set the scale
    of the systematic stds; E_d dominates a straight drive (heading drift ~ s (E_d - 1) / b). With
    these defaults ``benchmarks/odometry_drift.py`` (20 seeds, pure odometry, straight drive at
    0.2 m/s) measures a median (p90) heading error of 0.99 (2.2) deg and a position error of
    1.5 (2.6) % of the distance after 100 steps (2 m), and 4.4 (10.1) deg and 3.5 (8.8) % after
    10 m: "a few % of distance, several degrees per 10 m". The covariance's 1-sigma major axis is
    then of the order of the error (median error / sigma 0.7-0.8, p90 1.3-1.9).

    ``model: motion`` (the ``ideal`` preset, and the simulation before issue 13) instead measures
    the body's true displacement along its heading with relative Gaussian errors ``noise_v`` and
    ``noise_omega`` per control step (those two fields apply to ``motion`` only).
    """

    model: Literal["wheels", "motion"] = "wheels"
    """``wheels``: encoder model with the errors above; ``motion``: true motion + per-step noise."""
    noise_v: float = 0.02
    """``motion`` model: relative std of the travelled distance per control step (-)."""
    noise_omega: float = 0.03
    """``motion`` model: relative std of the turned angle per control step (-)."""
    diameter_ratio_std: float = 0.002
    """Std of E_d - 1, the right/left wheel-diameter ratio error, per robot per episode (-)."""
    scale_std: float = 0.01
    """Std of the mean wheel-diameter error (both wheels' distance scale), per robot per episode (-)."""
    wheelbase_std: float = 0.01
    """Std of E_b - 1, the effective wheel-base ratio error, per robot per episode (-)."""
    wheel_variance: float = 1e-6
    """Random error: variance of a wheel's distance error per metre that wheel travels (m^2/m)."""
    slip_accel: float = 0.01
    """Slip fraction per unit wheel acceleration (s^2/m)."""
    slip_turn: float = 0.005
    """Slip fraction per unit turn rate (s/rad)."""
    covariance_wheel_variance: float = 1e-5
    """Per-wheel distance variance per metre used to propagate the pose covariance (m^2/m)."""

    def __post_init__(self) -> None:
        for name in ("noise_v", "noise_omega", "diameter_ratio_std", "scale_std", "wheelbase_std",
                     "wheel_variance", "slip_accel", "slip_turn", "covariance_wheel_variance"):
            _check(getattr(self, name) >= 0, name, f"noise must be >= 0, got {getattr(self, name)}")
        for name in ("diameter_ratio_std", "scale_std", "wheelbase_std"):
            _check(getattr(self, name) <= 0.1, name,
                   f"a systematic error std above 10 % is not a calibrated robot, got {getattr(self, name)}")


@dataclass(frozen=True)
class RobotConfig:
    """A differential-drive robot modelled as a disc (unicycle kinematics)."""

    radius: float = 0.15
    max_speed: float = 0.3
    """Max linear speed v_max (m/s); action +-1 maps to +-max_speed."""
    max_turn_rate: float = 1.5
    """Max angular speed omega_max (rad/s)."""
    height: float = 0.3
    """Height of the robot's top, where the Kinect markers are (m)."""
    markers: bool = True
    """Whether leaders carry the retro-reflective markers the overhead Kinect detects (4 per robot)."""
    marker_radius: float = 0.02
    """Radius of each marker disc (m)."""
    sonar: SonarConfig = field(default_factory=SonarConfig)
    lidar: LidarConfig = field(default_factory=LidarConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)
    drive: DriveConfig = field(default_factory=DriveConfig)

    def __post_init__(self) -> None:
        _positive(self, "radius", "max_speed", "max_turn_rate", "height", "marker_radius")
        if self.drive.model == "wheels":
            _check(self.drive.wheel_speed_max >= self.max_speed, "drive.wheel_speed_max",
                   f"wheels limited to {self.drive.wheel_speed_max} m/s cannot reach max_speed {self.max_speed} m/s")
        _check(self.marker_radius <= 0.25 * self.radius, "marker_radius",
               f"4 markers of radius {self.marker_radius} m do not fit on a robot of radius {self.radius} m "
               f"(max {0.25 * self.radius:.3f} m)")


@dataclass(frozen=True)
class KinectConfig:
    """An overhead Kinect v1. Pitch is the tilt below horizontal (90 = straight down); yaw is
    the direction (from +x, counter-clockwise) the camera faces, projected on the floor."""

    name: str
    position: Point
    height: float = 2.8
    pitch_deg: float = 90.0
    yaw_deg: float = 90.0
    resolution: tuple[int, int] = (640, 480)
    fov_deg: tuple[float, float] = (57.0, 43.0)
    rate_hz: float = 15.0
    range_min: float = 0.8
    range_max: float = 4.0
    drop_rate: float = 0.0
    """Fault injection: probability that a frame is dropped."""
    wall_height: float = 0.5
    """Height of walls and obstacles as the depth camera sees them (m)."""
    mount_tilt_std_deg: float = 0.6
    """Mounting error of a hand-hung camera: sigma of its pitch and of its roll about the nominal
    pose (deg), drawn once per Kinect per episode. The localization pipeline keeps using the
    nominal pose, so this shifts every fix (1 deg at 2.8 m ~ 5 cm) (ALGORITHMS.md)."""
    mount_yaw_std_deg: float = 0.5
    """Mounting error sigma of the yaw about the optical axis direction (deg), per episode."""
    mount_height_std: float = 0.01
    """Mounting error sigma of the camera height (m), per episode."""
    lateral_noise_px: float = 0.8
    """Lateral depth noise (px): each depth pixel is sampled this far (sigma, per axis) from its
    own position, which blurs depth edges (Nguyen et al. 2012: ~0.8 px)."""

    def __post_init__(self) -> None:
        _positive(self, "height", "rate_hz", "range_max", "wall_height")
        for name in ("mount_tilt_std_deg", "mount_yaw_std_deg", "mount_height_std", "lateral_noise_px"):
            _check(getattr(self, name) >= 0, name, f"must be >= 0, got {getattr(self, name)}")
        for name in ("mount_tilt_std_deg", "mount_yaw_std_deg"):
            _check(getattr(self, name) <= 10, name, "mounting errors above 10 deg sigma are not a mounting error")
        _check(self.mount_height_std <= 0.5, "mount_height_std", f"must be <= 0.5 m, got {self.mount_height_std}")
        _check(self.lateral_noise_px <= 5, "lateral_noise_px", f"must be <= 5 px, got {self.lateral_noise_px}")
        _check(0 < self.pitch_deg <= 90, "pitch_deg", f"must be in (0, 90] (90 = looking down), got {self.pitch_deg}")
        _check(self.pitch_deg - self.fov_deg[1] / 2 > 0, "pitch_deg",
               "the top of the image looks at or above the horizon: the footprint would not be on the floor")
        for i, r in enumerate(self.resolution):
            _check(16 <= r <= 4096, f"resolution[{i}]", f"must be in [16, 4096], got {r}")
        for i, f in enumerate(self.fov_deg):
            _check(0 < f < 170, f"fov_deg[{i}]", f"must be in (0, 170), got {f}")
        _check(0 <= self.range_min < self.range_max, "range_min", "must satisfy 0 <= range_min < range_max")
        _check(0 <= self.drop_rate <= 1, "drop_rate", "must be in [0, 1]")
