"""The stepper's contract with a world: :class:`StepWorld` names every attribute the phases of
:mod:`parcover_env.sim.pipeline` read or write of one world, with its type, and :class:`Layout` and
:class:`Features` what they call of the env's observation layout and feature set.

``ParallelCoverageEnv`` after ``reset`` is one (``isinstance(env, StepWorld)``; the batched worlds
are ``K`` of them); ``tests/sim/test_contract.py`` checks that and that the names here are exactly
those the phases use.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, NamedTuple, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:  # annotations only: the phases import this module
    from parcover_env.config import Scenario
    from parcover_env.localization.estimator import PoseEstimator
    from parcover_env.localization.kinect.system import KinectSystem
    from parcover_env.localization.sonar.service import SonarFixes
    from parcover_env.mission.metrics import EpisodeMetrics
    from parcover_env.mission.team import CameraView, Team
    from parcover_env.scenarios.progress import RouteTracker
    from parcover_env.sensors.base import Sensor
    from parcover_env.sensors.relative import RelativeCamera
    from parcover_env.world.map_model import MapModel
    from parcover_env.world.physics import World

__all__ = ["StepWorld", "Layout", "Features", "WorldGroup", "ScoreState", "ScalarInputs", "ObsInputs"]


class ScalarInputs(NamedTuple):
    """What the observation layout's compiled pass reads (``layout.fill_scalars``), per robot ``(N, ...)``
    and team-wide (for ``layout.fill_scalars_many``, every field with a leading worlds axis ``K``)."""

    est: np.ndarray
    """Pose estimates ``(N, 3)``."""
    velocity: np.ndarray
    """Encoder ``(v, omega)`` ``(N, 2)``."""
    leader: np.ndarray
    """Leader flags ``(N,)`` bool."""
    slot: np.ndarray
    """Column slots ``(N,)`` int (reported / ``max(N - 1, 1)``)."""
    fix_age: np.ndarray
    """Seconds since the last absolute fix ``(N,)`` (reported capped at ``obs_spec.MAX_FIX_AGE``)."""
    covariance: np.ndarray
    """Pose covariances ``(N, 3, 3)``."""
    goals: np.ndarray
    """Lookahead waypoints ``(N, 2)``, world frame."""
    rel_xy: np.ndarray
    """The follower camera's predecessor position ``(N, 2)``, robot frame."""
    rel_heading: np.ndarray
    """Its relative heading ``(N,)``."""
    visible: np.ndarray
    """Predecessor seen ``(N,)`` bool."""
    kpois_visited: float
    """Fraction of KPOIs visited by the team."""
    time: float
    """Fraction of the step limit elapsed."""


class ObsInputs(NamedTuple):
    """What a feature set's own fill functions read (``world.features.fills``), ``K`` worlds at once."""

    scalars: ScalarInputs
    """The compiled pass's inputs ``(K, N, ...)`` (estimates, encoder velocities, leader flags, ...)."""
    waypoint: np.ndarray
    """``(K, N)`` int64 index of each robot's next route vertex (the route tracker's)."""
    plan_progress: np.ndarray
    """``(K, N)`` progress along the plan path (m)."""
    visited: np.ndarray
    """``(K, M)`` bool, the KPOIs visited."""


class ScoreState:
    """What scoring carries over from one step of a world to the next: arrays made here and never
    rebound (the score phase writes them in place, as rows of ``(K, ...)`` blocks when the world is
    scored with others: :func:`score_blocks`)."""

    def __init__(self, remaining: np.ndarray, wall: np.ndarray, robot: np.ndarray):
        self.remaining = remaining
        """``(N,)`` route length to go at the last step (m): the ``progress`` term's potential."""
        self.wall = wall
        """``(N,)`` int64 wall contacts of each robot counted up to the last step."""
        self.robot = robot
        """``(N,)`` int64 robot contacts of each robot counted up to the last step."""

    @property
    def contacts(self) -> tuple[np.ndarray, np.ndarray]:
        """Wall and robot contacts of each robot counted up to the last step ``(N,)`` each."""
        return self.wall, self.robot

    @classmethod
    def start(cls, remaining: np.ndarray) -> ScoreState:
        """At reset: the route length to go ``(N,)``, no contacts yet."""
        n = len(remaining)
        return cls(np.array(remaining, dtype=float), np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64))


class WorldGroup(Protocol):
    """The score blocks a world was attached to last (:class:`~parcover_env.sim.score_phase.ScoreGroup`)."""

    def fits(self, worlds: Sequence[StepWorld]) -> bool:
        """True if the blocks can hold ``worlds``."""

    def holds(self, worlds: Sequence[StepWorld]) -> bool:
        """True if ``worlds`` were attached to these blocks last, in this order."""

    def attach(self, worlds: Sequence[StepWorld]) -> None:
        """Make the worlds' arrays rows of these blocks."""


@runtime_checkable
class Layout(Protocol):
    """What the stepper uses of a world's observation layout (``envs.observations.ObservationLayout``)."""

    slices: dict[str, slice]
    """Each entry's columns."""

    @property
    def size(self) -> int:
        """Columns ``D`` of one observation."""

    def fill_scalars_many(self, obs: np.ndarray, inputs: ScalarInputs) -> None:
        """Write the compiled pass's entries of ``obs (K, N, D)``."""

    def clip(self, obs: np.ndarray) -> np.ndarray:
        """Clip ``obs`` into the bounds in place."""


@runtime_checkable
class Features(Protocol):
    """What the stepper uses of a world's feature set (``envs.feature_sets``: an observation version)."""

    fills: tuple[Callable[[np.ndarray, dict[str, slice], ObsInputs], None], ...]
    """Functions writing the set's own entries of ``obs (K, N, D)``, all worlds at once."""
    info: tuple[tuple[str, Callable[[np.ndarray], np.ndarray]], ...]
    """``(key, column)``: the set's own per-agent info values ``(K, N)`` from the KPOIs visited ``(K, M)``."""


@runtime_checkable
class StepWorld(Protocol):
    """One world as the stepper sees it (an env after ``reset``): what the act, score, observe and
    outputs phases read, and the few attributes they write (marked *written*)."""

    # the scenario and its static parts
    scenario: Scenario
    """The world's scenario (the worlds stepped together share one)."""
    map: MapModel
    """The true map (walls the sensors see)."""
    n_robots: int
    kpoi_owner: np.ndarray
    """``(n_kpois,)`` the robot whose route the plan credits with each KPOI."""
    terms: tuple[str, ...]
    """The reward terms, in summing order."""
    layout: Layout
    features: Features
    sensors: Mapping[str, Sensor | None]
    """The sensor of each ``sensor`` entry of the observation spec (None = off)."""
    camera: RelativeCamera
    """The follower cameras."""
    kinects: KinectSystem | None
    """The overhead Kinect system (None: no Kinect fixes)."""
    scanner: SonarFixes | None
    """The sonar localization service (None: ``observation.scan`` off)."""
    render_mode: str | None

    # the episode's state
    agents: list[str]
    """The live agents (*written*: cleared when the episode ends)."""
    steps: int
    """Control steps taken (*written*)."""
    world: World
    """The pymunk world: bodies, drive, contacts, time."""
    estimator: PoseEstimator
    team: Team
    progress: RouteTracker
    metrics: EpisodeMetrics
    score_state: ScoreState
    score_group: WorldGroup | None
    """The score blocks it was attached to last (*written*; None: none, as in a copy)."""
    commands: np.ndarray
    """``(N, 2)`` this step's commands (*written*)."""
    true_velocity: np.ndarray
    """``(N, 2)`` the last step's true velocity (*written*)."""
    trails: list[list[np.ndarray]]
    """Each robot's true positions so far (*written* when rendering)."""
    camera_views: CameraView | None
    """The cameras' measurements of the worlds observed together (*written*)."""
    camera_index: int
    """This world's row of :attr:`camera_views` (*written*)."""

    @property
    def np_random(self) -> np.random.Generator:
        """The world's own generator."""

    @property
    def estimate(self) -> np.ndarray:
        """The pose estimates ``(N, 3)``."""

    @property
    def camera_view(self) -> CameraView | None:
        """This world's row of :attr:`camera_views`."""

    def localization_entries(self) -> dict[str, np.ndarray]:
        """The ``scan`` entries of the observation, ``{name: (N,)}``."""
