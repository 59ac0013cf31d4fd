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
from parcover_env.geometry.stacking import stack
from parcover_env.localization.kinect.batch_update import update_systems
from parcover_env.localization.kinect.system import KinectSystem
from parcover_env.sensors.odometry import Odometry, measure_wheels_all
from parcover_env.world.drive import take_travel_all, wheel_targets

__all__ = ["FixRequest", "FixSource", "KinectFixes", "PoseEstimator", "update_all"]


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
        :class:`~parcover_env.world.drive.DiffDrive`, or the ``commands (N, 2)`` for an instant
        drive; the true motion for the ``motion`` odometry model), then every source's fixes.
        Returns each source's fixes of this step by source name. :func:`update_all` with ``K = 1``."""
        return update_all([self], [true], [commands], [drive], [time], [leaders], [rng])[0]

    def fix(self, i: int, pose, cov: np.ndarray | None = None) -> None:
        """Reset robot ``i``'s belief to an absolute fix ``pose (3,)`` of covariance ``cov (3, 3)``."""
        self.odometry.fix(i, pose, cov)
        self.fix_age[i] = 0.0


def update_all(estimators: Sequence[PoseEstimator], true: Sequence[np.ndarray], commands: Sequence[np.ndarray],
               drives: Sequence, times: Sequence[float], leaders: Sequence[np.ndarray],
               rngs: Sequence[np.random.Generator]) -> list[dict[str, dict[int, np.ndarray]]]:
    """:meth:`PoseEstimator.update` of ``K`` estimators of one scenario (``N`` robots each) at once:
    ``true`` ``(K, N, 3)``, ``commands`` ``(K, N, 2)``, ``leaders`` ``(K, N)`` (arrays, or sequences of
    the ``K`` worlds' arrays: the sources see those very arrays), and per estimator its
    world's drive, time and generator. The wheel odometry of all ``K N`` robots runs in one compiled
    call and the Kinect systems in one batch (:func:`~parcover_env.localization.kinect.batch_update.update_systems`);
    estimator ``k`` draws from ``rngs[k]`` in the order it would alone (odometry, then each source in
    turn), so its results are the same floats. Returns each estimator's fixes by source name."""
    s = estimators[0].scenario
    dt = s.physics.control_dt
    k = len(estimators)
    if s.robot.odometry.model == "wheels":
        if drives[0] is not None:
            travel_all, change_all = take_travel_all(list(drives))
        else:  # instant drive: the wheels turned at the commanded speeds all step
            cmd = np.asarray(commands, dtype=float)
            travel_all = wheel_targets(cmd.reshape(-1, 2), s.robot.drive.wheel_base, np.inf).reshape(cmd.shape) * dt
            change_all = np.zeros_like(travel_all)
        before = stack([e.odometry.estimate for e in estimators], copy=True)
        est = measure_wheels_all([e.odometry for e in estimators], travel_all, change_all, dt, list(rngs))
        velocity = np.empty((k, est.shape[1], 2))  # (signed distance, heading change) over the step / dt
        np.multiply(np.hypot(est[..., 0] - before[..., 0], est[..., 1] - before[..., 1]),
                    np.sign(travel_all[..., 0] + travel_all[..., 1]), out=velocity[..., 0])
        velocity[..., 1] = wrap_angle(est[..., 2] - before[..., 2])
        velocity /= dt
        for e, v in zip(estimators, velocity, strict=True):
            e.velocity = v
    else:
        for e, t, cmd, rng in zip(estimators, true, commands, rngs, strict=True):
            e.odometry.measure(t, rng)
            e.velocity = cmd
    fixed: list[dict[str, dict[int, np.ndarray]]] = [{} for _ in estimators]
    for e in estimators:
        e.fix_age += dt
        e.estimate = e.odometry.estimate
    if s.observation.pose_source == "ground_truth":
        for e, t in zip(estimators, true, strict=True):
            e.odometry.set_truth(t)
            e.fix_age[:] = 0.0
        return fixed
    for j in range(len(estimators[0].sources)):  # each source in turn, all estimators
        sources = [e.sources[j] for e in estimators]
        if all(isinstance(src, KinectFixes) for src in sources):
            markers = np.asarray(leaders, dtype=bool) & np.array([src.markers for src in sources])[:, None]
            fixes = update_systems([src.system for src in sources], list(times), np.asarray(true, dtype=float),
                                   markers, stack([e.estimate for e in estimators]), list(rngs))
        else:
            fixes = [src.fixes(FixRequest(time, t, e.estimate, lead, e.covariance), rng) for e, src, time, t, lead, rng
                     in zip(estimators, sources, times, true, leaders, rngs, strict=True)]
        for e, src, f, out in zip(estimators, sources, fixes, fixed, strict=True):
            out[src.name] = f
            for i, pose in f.items():
                e.fix(i, pose, src.covariance)
    return fixed
