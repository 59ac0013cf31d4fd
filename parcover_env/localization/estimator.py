"""The pose estimator every robot gets from the env: odometry dead reckoning plus absolute fixes.

Each step :meth:`PoseEstimator.update` advances every robot's belief by its wheel odometry
(:class:`~parcover_env.sensors.odometry.Odometry`: estimate and Chong & Kleeman covariance), then
asks each fix source in turn for absolute pose fixes and resets the fixed robots' beliefs
(:meth:`PoseEstimator.fix`). A fix source is anything with the :class:`FixSource` shape: the overhead
Kinect system (:class:`KinectFixes`, Min, Fehr & Papanikolopoulos) and the sonar localizer fix of a
robot that stops and scans (Kim, Pearce & Amato; :class:`~parcover_env.localization.sonar.service.SonarFixes`,
``observation.scan``), in that order.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import chain
from operator import attrgetter, is_
from typing import NamedTuple, Protocol

import numpy as np

from parcover_env.config import Scenario
from parcover_env.localization.kinect.batch_update import update_systems
from parcover_env.localization.kinect.system import KinectSystem
from parcover_env.sensors.odometry import Odometry
from parcover_env.sensors.onboard_kernels import OdometryState, wheel_odometry_rows
from parcover_env.world.batching import SharedRows
from parcover_env.world.drive import DiffDrive, wheel_targets

__all__ = ["FixRequest", "FixSource", "KinectFixes", "PoseEstimator", "update_all", "ActRows", "act_rows",
           "ESTIMATOR", "ODOMETRY", "DRIVE", "KINECT"]


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
        self.kinect_system: KinectSystem | None = next((s.system for s in self.sources if isinstance(s, KinectFixes)),
                                                       None)
        """The system of the first Kinect source (None: none)."""
        for source in self.sources:
            source.reset(rng)
        self.estimate = true.copy()
        self.velocity = np.zeros((len(true), 2))
        self.fix_age = np.zeros(len(true))
        self.act_rows: ActRows | None = None
        """The shared rows this estimator's arrays are views of, when it steps with others
        (:func:`act_rows`); not copied, not pickled."""

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["act_rows"] = None  # a copy owns plain arrays (numpy copies the views' values)
        return state

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
               rngs: Sequence[np.random.Generator],
               rows: ActRows | None = None) -> list[dict[str, dict[int, np.ndarray]]]:
    """:meth:`PoseEstimator.update` of ``K`` estimators of one scenario (``N`` robots each) at once:
    ``true`` ``(K, N, 3)``, ``commands`` ``(K, N, 2)``, ``leaders`` ``(K, N)`` (arrays, or sequences of
    the ``K`` worlds' arrays: the sources see those very arrays), and per estimator its
    world's drive, time and generator; ``rows``: their shared rows
    (:func:`act_rows`, made here if not given). The wheel odometry of
    all ``K N`` robots (dead reckoning, encoder velocity, fix age) runs in one compiled call on the
    rows, the Kinect systems in one batch
    (:func:`~parcover_env.localization.kinect.batch_update.update_systems`), and each source's fixes
    are written into the rows together; estimator ``k`` draws from ``rngs[k]`` in the order it
    would alone (odometry, then each source in turn), so its results are the same floats. Returns
    each estimator's fixes by source name."""
    s = estimators[0].scenario
    dt = s.physics.control_dt
    k = len(estimators)
    rows = act_rows(estimators, drives) if rows is None else rows
    if s.robot.odometry.model == "wheels":
        if rows.drives is not None:
            travel, change = rows.drives.flat["travel"], rows.drives.flat["speed_change"]
        else:  # instant drive: the wheels turned at the commanded speeds all step
            cmd = np.asarray(commands, dtype=float).reshape(-1, 2)
            travel = wheel_targets(cmd, s.robot.drive.wheel_base, np.inf) * dt
            change = np.zeros_like(travel)
        n = rows.odometry.views["estimate"][0].shape[0]
        z = np.empty((k, 4 * n))
        for row, rng in zip(z, rngs, strict=True):  # each odometry's normals from its own generator
            rng.standard_normal(out=row)
        o, mine = rows.odometry.flat, rows.estimators.flat
        state = OdometryState(o["estimate"], o["covariance"], o["travelled"], o["turned"], o["factors"],
                              o["believed_base"])
        wheel_odometry_rows(state, travel, change, float(dt), z, estimators[0].odometry.wheel_errors, mine["velocity"],
                            mine["fix_age"])
    else:
        for e, t, cmd, rng in zip(estimators, true, commands, rngs, strict=True):
            e.odometry.measure(t, rng)
            e.velocity[:] = cmd  # in place: the shared rows stay attached
            e.fix_age += dt
    fixed: list[dict[str, dict[int, np.ndarray]]] = [{} for _ in estimators]
    for e in estimators:
        e.estimate = e.odometry.estimate
    if s.observation.pose_source == "ground_truth":
        for e, t in zip(estimators, true, strict=True):
            e.odometry.set_truth(t)
            e.fix_age[:] = 0.0
        return fixed
    for j in range(len(estimators[0].sources)):  # each source in turn, all estimators
        sources = [e.sources[j] for e in estimators]
        estimates = rows.odometry.blocks["estimate"]
        if all(isinstance(src, KinectFixes) for src in sources):
            markers = np.asarray(leaders, dtype=bool)
            if not all(src.markers for src in sources):  # the leaders that carry markers
                markers = markers & np.array([src.markers for src in sources])[:, None]
            systems = [src.system for src in sources]
            shared = rows.kinect is not None and rows.kinect.owners[0] is systems[0]  # their ticks are its rows
            fixes = update_systems(systems, list(times), np.asarray(true, dtype=float), markers, estimates, list(rngs),
                                   ticks=rows.kinect.blocks["next_tick"] if shared else None)
        else:
            fixes = [src.fixes(FixRequest(time, t, e.estimate, lead, e.covariance), rng) for e, src, time, t, lead, rng
                     in zip(estimators, sources, times, true, leaders, rngs, strict=True)]
        for f, src, out in zip(fixes, sources, fixed, strict=True):
            out[src.name] = f
        _apply_fixes(rows, fixes, sources[0].covariance)
    return fixed


def _apply_fixes(rows: ActRows, fixes: Sequence[dict[int, np.ndarray]], cov: np.ndarray | None) -> None:
    """:meth:`PoseEstimator.fix` of every ``fixes[k]`` ``{robot: pose}`` of estimator ``k`` (one
    source, its fix covariance ``cov``), on the shared rows in a few numpy calls."""
    counts = list(map(len, fixes))
    total = sum(counts)
    o, fix_age = rows.odometry.blocks, rows.estimators.blocks["fix_age"]
    est, covariance, travelled, turned = o["estimate"], o["covariance"], o["travelled"], o["turned"]
    cov = 0.0 if cov is None else cov
    if total <= _FEW_FIXES:  # a few rows: written one by one (numpy's fancy indexing costs more)
        for k, f in enumerate(fixes):
            for i, pose in f.items():
                est[k, i] = pose
                covariance[k, i] = cov
                travelled[k, i] = turned[k, i] = fix_age[k, i] = 0.0
        return
    at = (np.repeat(np.arange(len(fixes)), counts), np.fromiter(chain.from_iterable(fixes), np.int64, total))
    est[at] = list(chain.from_iterable(f.values() for f in fixes))
    covariance[at] = cov
    travelled[at] = 0.0
    turned[at] = 0.0
    fix_age[at] = 0.0


_FEW_FIXES = 4
"""Up to this many fixes are written row by row."""


class ActRows(NamedTuple):
    """The act phase's per-robot state of ``K`` worlds as shared rows (:func:`act_rows`)."""

    estimators: SharedRows
    """The pose estimators' :data:`ESTIMATOR` arrays."""
    odometry: SharedRows
    """Their wheel odometries' :data:`ODOMETRY` arrays."""
    drives: SharedRows | None
    """The worlds' drives' :data:`DRIVE` arrays (None: no drive, ``drive: instant``)."""
    kinect: SharedRows | None = None
    """The estimators' Kinect systems' :data:`KINECT` arrays (None: no Kinect source, or ``K = 1``)."""


ESTIMATOR = ("velocity", "fix_age")
"""Rows of :class:`PoseEstimator`."""
ODOMETRY = ("estimate", "covariance", "travelled", "turned", "factors", "believed_base")
"""Rows of :class:`~parcover_env.sensors.odometry.Odometry`."""
DRIVE = ("wheels", "travel", "speed_change")
"""Rows of :class:`~parcover_env.world.drive.DiffDrive`."""
KINECT = ("next_tick",)
"""Rows of :class:`~parcover_env.localization.kinect.system.KinectSystem` (each Kinect's next frame time)."""


def act_rows(estimators: Sequence[PoseEstimator], drives: Sequence[DiffDrive | None]) -> ActRows:
    """The shared rows of ``K`` worlds' pose ``estimators`` (of one scenario), their Kinect systems
    (``kinect_system``) and their ``drives`` (``None`` s for ``drive: instant``), every array attached
    (:meth:`SharedRows.attach`). The rows are kept on the estimators (``act_rows``, never copied or
    pickled) and reused while they fit. When every estimator, odometry, Kinect system and drive
    still holds the very objects it held when last attached (the common step), one identity check
    per world replaces the attach passes."""
    first = estimators[0]
    rows = first.act_rows
    if rows is not None and _unchanged(rows, estimators, drives):
        return rows
    if rows is None:  # after world 0's reset: the rows another world holds
        rows = next((e.act_rows for e in estimators if e.act_rows is not None), None)
    k = len(estimators)
    if rows is None or rows.estimators.size != k or not (_holds(rows, first, drives[0])
                                                         or _fits(rows, k, first, drives[0])):
        rows = ActRows(SharedRows(k, ESTIMATOR, first), SharedRows(k, ODOMETRY, first.odometry),
                       None if drives[0] is None else SharedRows(k, DRIVE, drives[0]))
    rows.estimators.attach(estimators)
    rows.odometry.attach([e.odometry for e in estimators])
    if rows.drives is not None:
        rows.drives.attach(drives)
    if k > 1:  # K = 1 updates its one system's ticks in place already
        rows = _with_kinect(rows, k, [e.kinect_system for e in estimators])
    for e in estimators:
        if e.act_rows is not rows:
            e.act_rows = rows
    _remember(rows, estimators, drives)
    return rows


def _getter(rows: ActRows):
    """``f(estimator, drive)``: the objects and arrays of one world that :func:`act_rows` attaches."""
    names = ["act_rows", "kinect_system", *ESTIMATOR, *(f"odometry.{n}" for n in ODOMETRY)]
    if rows.kinect is not None:
        names += [f"kinect_system.{n}" for n in KINECT]
    mine = attrgetter(*names)
    if rows.drives is None:
        return lambda e, d: (*mine(e), d)
    theirs = attrgetter(*DRIVE)
    return lambda e, d: (*mine(e), d, *theirs(d))


def _remember(rows: ActRows, estimators: Sequence[PoseEstimator], drives: Sequence[DiffDrive | None]) -> None:
    """Keep what every world holds now that ``rows`` are attached (for :func:`_unchanged`)."""
    get = _getter(rows)
    rows.estimators.memo = (rows, get, [get(e, d) for e, d in zip(estimators, drives, strict=True)])


def _unchanged(rows: ActRows, estimators: Sequence[PoseEstimator], drives: Sequence[DiffDrive | None]) -> bool:
    """True if every world still holds what it held when ``rows`` were last attached to these
    estimators and drives (so all of them are attached)."""
    memo = rows.estimators.memo
    if memo is None or memo[0] is not rows or len(memo[2]) != len(estimators):
        return False
    get = memo[1]
    return all(all(map(is_, get(e, d), held)) for e, d, held in zip(estimators, drives, memo[2], strict=True))


def _with_kinect(rows: ActRows, k: int, systems: Sequence[KinectSystem | None]) -> ActRows:
    """``rows`` with the Kinect ``systems``' rows attached (made when missing or not fitting); without
    rows for them when some world has no Kinect system."""
    if any(s is None for s in systems):
        return rows if rows.kinect is None else ActRows(rows.estimators, rows.odometry, rows.drives)
    if rows.kinect is None or not rows.kinect.fits(k, systems[0]):
        rows = ActRows(rows.estimators, rows.odometry, rows.drives, SharedRows(k, KINECT, systems[0]))
    rows.kinect.attach(systems)
    return rows


def _holds(rows: ActRows, estimator: PoseEstimator, drive: DiffDrive | None) -> bool:
    """True if ``estimator`` (and its odometry and ``drive``) hold row 0 of ``rows`` (so they fit)."""
    return (rows.estimators.attached(0, estimator) and rows.odometry.attached(0, estimator.odometry)
            and (drive is None if rows.drives is None else rows.drives.attached(0, drive)))


def _fits(rows: ActRows, k: int, estimator: PoseEstimator, drive: DiffDrive | None) -> bool:
    """True if ``rows`` can hold ``k`` worlds like ``estimator``'s (and its odometry's and ``drive``'s)."""
    return (rows.estimators.fits(k, estimator) and rows.odometry.fits(k, estimator.odometry)
            and (rows.drives is None) == (drive is None) and (drive is None or rows.drives.fits(k, drive)))
