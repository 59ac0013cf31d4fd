"""The pose estimator every robot gets from the env: odometry dead reckoning plus absolute fixes.

Each step :meth:`PoseEstimator.update` advances every robot's belief by its wheel odometry
(:class:`~parcover_env.sensors.odometry.Odometry`: estimate and Chong & Kleeman covariance), then
asks each fix source in turn for absolute pose fixes and resets the fixed robots' beliefs
(:meth:`PoseEstimator.fix`). A fix source is anything with the :class:`FixSource` shape: the overhead
Kinect system (:class:`KinectFixes`, Min, Fehr & Papanikolopoulos) and the sonar localizer fix of a
robot that stops and scans (Kim, Pearce & Amato; :class:`~parcover_env.envs.sonar_fixes.SonarFixes`,
``observation.scan``), in that order.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, Protocol

import numpy as np

from parcover_env.config import Scenario
from parcover_env.geometry import wrap_angle
from parcover_env.localization.kinect.system import KinectSystem
from parcover_env.sensors.odometry import Odometry
from parcover_env.world.drive import wheel_targets

__all__ = ["FixRequest", "FixSource", "KinectFixes", "PoseEstimator"]


class FixRequest(NamedTuple):
    """What a fix source may read at one step."""

    time: float
    """Simulated time (s)."""
    true: np.ndarray
    """True poses ``(N, 3)`` (what the external sensor observes)."""
    estimate: np.ndarray
    """The dead-reckoned estimates ``(N, 3)`` of this step, before any fix."""
    leaders: np.ndarray
    """``(N,)`` bool: the robots leading a group."""
    covariance: np.ndarray | None = None
    """The covariances ``(N, 3, 3)`` of those estimates (the prior of a localizer; read only)."""


class FixSource(Protocol):
    """A source of absolute pose fixes."""

    name: str
    covariance: np.ndarray
    """Covariance ``(3, 3)`` of one fix (m^2, m rad, rad^2)."""

    def reset(self, rng: np.random.Generator) -> None:
        """New episode (draw per-episode errors from ``rng``)."""

    def fixes(self, request: FixRequest, rng: np.random.Generator) -> dict[int, np.ndarray]:
        """``{robot index: pose (3,)}`` fixed this step."""


class KinectFixes:
    """The overhead Kinect system as a fix source: the marker-carrying leaders it detects."""

    name = "kinect"

    def __init__(self, system: KinectSystem, markers: bool, covariance: np.ndarray):
        self.system, self.markers, self.covariance = system, bool(markers), covariance

    def reset(self, rng: np.random.Generator) -> None:
        self.system.reset(rng)

    def fixes(self, request: FixRequest, rng: np.random.Generator) -> dict[int, np.ndarray]:
        return self.system.update(request.time, request.true, request.leaders & self.markers, request.estimate, rng)


class PoseEstimator:
    """Every robot's pose belief: :attr:`estimate` ``(N, 3)``, :attr:`covariance` ``(N, 3, 3)``,
    encoder :attr:`velocity` ``(N, 2)`` and :attr:`fix_age` ``(N,)`` (s since the last fix).

    Built at ``reset``: draws the odometry's systematic errors, then resets every source, from ``rng``.
    """

    def __init__(self, scenario: Scenario, true: np.ndarray, rng: np.random.Generator,
                 sources: Sequence[FixSource] = ()):
        self.scenario = scenario
        self.odometry = Odometry(scenario.robot.odometry, true, scenario.robot.drive.wheel_base, rng)
        self.sources = list(sources)
        for source in self.sources:
            source.reset(rng)
        self.estimate = true.copy()
        self.velocity = np.zeros((len(true), 2))
        self.fix_age = np.zeros(len(true))

    @property
    def covariance(self) -> np.ndarray:
        return self.odometry.covariance

    def update(self, true: np.ndarray, commands: np.ndarray, drive, time: float, leaders: np.ndarray,
               rng: np.random.Generator) -> dict[str, dict[int, np.ndarray]]:
        """One control step: dead reckoning (the wheel travel of ``drive``, the world's
        :class:`~parcover_env.world.drive.DriveTrain`, or the ``commands (N, 2)`` for an instant
        drive; the true motion for the ``motion`` odometry model), then every source's fixes.
        Returns each source's fixes of this step by source name."""
        s = self.scenario
        dt = s.physics.control_dt
        if s.robot.odometry.model == "wheels":
            if drive is not None:
                travel, change = drive.take_travel()
            else:  # instant drive: the wheels turned at the commanded speeds all step
                travel = wheel_targets(commands, s.robot.drive.wheel_base, np.inf) * dt
                change = np.zeros_like(travel)
            before = self.odometry.estimate.copy()
            est = self.odometry.measure_wheels(travel, change, dt, rng)
            velocity = np.empty((len(est), 2))  # (signed distance, heading change) over the step / dt
            np.multiply(np.hypot(est[:, 0] - before[:, 0], est[:, 1] - before[:, 1]),
                        np.sign(travel[:, 0] + travel[:, 1]), out=velocity[:, 0])
            velocity[:, 1] = wrap_angle(est[:, 2] - before[:, 2])
            velocity /= dt
            self.velocity = velocity
        else:
            est = self.odometry.measure(true, rng)
            self.velocity = commands
        self.fix_age += dt
        self.estimate = est
        fixed: dict[str, dict[int, np.ndarray]] = {}
        if s.observation.pose_source == "ground_truth":
            self.odometry.set_truth(true)
            self.fix_age[:] = 0.0
            return fixed
        for source in self.sources:
            fixes = fixed[source.name] = source.fixes(FixRequest(time, true, est, leaders, self.covariance), rng)
            for i, pose in fixes.items():
                self.fix(i, pose, source.covariance)
        return fixed

    def fix(self, i: int, pose, cov: np.ndarray | None = None) -> None:
        """Reset robot ``i``'s belief to an absolute fix ``pose (3,)`` of covariance ``cov (3, 3)``."""
        self.odometry.fix(i, pose, cov)
        self.fix_age[i] = 0.0
