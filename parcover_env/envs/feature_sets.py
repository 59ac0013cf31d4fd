"""Observation versions as named feature sets: the registry :data:`FEATURE_SETS`, keyed by
``observation.version``.

A feature set owns what its version adds to the env: the sources of its observation entries (the
spec's entries, :data:`~parcover_env.envs.obs_spec.ENTRIES`, of those sources make its
observation), its reward terms (before the optional ``contact`` and ``uncertainty``), the functions
that fill its own entries and its own per-agent info values, and its critic state
(``env.state()``) with its bounds. The env makes one at construction (``env.features``); the
stepper (:mod:`parcover_env.sim.pipeline`) calls its :attr:`~CoreFeatures.fills` and
:attr:`~CoreFeatures.info` for all worlds at once and never asks for a version number.

* :class:`CoreFeatures` (version 1, ``parcover_v1``): the robot's estimate, team role, mission
  fractions, follower camera, sensors and scan service; the terms
  :data:`~parcover_env.mission.rewards.TERMS`; the true-pose state of :func:`~parcover_env.envs.critic_state.state_v1`.
* :class:`RouteFeatures` (version 2, ``parcover_v2``): also the ``route`` and ``teammates`` entries
  (:func:`parcover_env.envs.obs_v2.fill`), ``info[agent]["route_done"]``, the ``own_kpoi`` term
  first (:data:`~parcover_env.mission.rewards.TERMS_V2`) and the token state of
  :func:`~parcover_env.envs.critic_state.global_state`.

A new version is a subclass here and an entry of :data:`FEATURE_SETS` (plus its entries in the spec).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from parcover_env.envs import critic_state
from parcover_env.envs.obs_spec import VERSION_SOURCES
from parcover_env.envs.obs_v2 import RouteFacts, TeamRows, fill, group_sizes, route_facts, target_kpois
from parcover_env.errors import ParcoverError
from parcover_env.mission.rewards import TERMS, TERMS_V2
from parcover_env.sim.pipeline import ObsInputs

__all__ = ["CoreFeatures", "RouteFeatures", "FEATURE_SETS", "feature_set"]

Fill = Callable[[np.ndarray, dict[str, slice], ObsInputs], None]
"""Writes a feature set's own entries of ``obs (K, N, D)`` (the layout's ``slices``) from the step's inputs."""
InfoColumn = Callable[[np.ndarray], np.ndarray]
"""An info value ``(K, N)`` of every agent from the KPOIs visited ``(K, M)``."""


class CoreFeatures:
    """Observation version 1 (``parcover_v1``): the entries the compiled pass, the sensors and the scan
    service write; no entries, info values or terms of its own beyond those."""

    version: ClassVar[int] = 1
    name: ClassVar[str] = "parcover_v1"
    sources: ClassVar[tuple[str, ...]] = VERSION_SOURCES[1]
    """The observation spec's entry sources this version's observation holds."""
    terms: ClassVar[tuple[str, ...]] = TERMS
    """Its reward terms, in summing order (``contact`` and ``uncertainty`` follow when weighted)."""

    def __init__(self, env: Any):
        self.route_facts: RouteFacts | None = None
        """The routes' static facts the version's entries and state read (None: it reads none)."""
        self.fills: tuple[Fill, ...] = ()
        """The functions that write this version's own entries, all worlds at once."""
        self.info: tuple[tuple[str, InfoColumn], ...] = ()
        """``(key, column)``: this version's own per-agent info values, after ``sonar_fix``."""
        self.state_space: spaces.Box = critic_state.state_space_v1(env.map.bounds, env.n_robots,
                                                                   len(env.scenario.kpois))
        """The bounds of :meth:`state`."""

    def state(self, env: Any) -> np.ndarray:
        """The global state of ``env`` for a centralized critic."""
        return critic_state.state_v1(env)

    def route_done(self, env: Any) -> np.ndarray:
        """``(N,)`` bool, every KPOI of each robot's own route visited; version 1 has no routes of its own."""
        raise ParcoverError(f"route_done() needs observation.version 2 (parcover_v2); this env is version "
                            f"{self.version}")


class RouteFeatures(CoreFeatures):
    """Observation version 2 (``parcover_v2``): version 1 plus what a robot needs to drive, wait, follow
    or split (the ``route`` and ``teammates`` entries), ``route_done`` in every agent's info, the
    per-robot ``own_kpoi`` term first, and one state shape on every map (robot and KPOI tokens).
    Raises a ``ConfigError`` for a scenario with more robots or KPOIs than the state holds."""

    version: ClassVar[int] = 2
    name: ClassVar[str] = "parcover_v2"
    sources: ClassVar[tuple[str, ...]] = VERSION_SOURCES[2]
    terms: ClassVar[tuple[str, ...]] = TERMS_V2

    def __init__(self, env: Any):
        s = env.scenario
        critic_state.check_maxima(s, env.n_robots)
        table = env.mission.tracker().table
        self.route_facts = route_facts(env.plan, table.pts, table.length, env.mission.kpois)
        self.neighbours = s.observation.neighbours
        """Teammate slots ``k`` of the ``mate_*`` entries."""
        self.fills = (self.fill,)
        self.info = (("route_done", self.done_column),)
        self.state_space = critic_state.state_space(s, env.map.bounds)

    def fill(self, obs: np.ndarray, slices: dict[str, slice], x: ObsInputs) -> None:
        """The ``route`` and ``teammates`` entries of every robot of the ``K`` worlds
        (:func:`~parcover_env.envs.obs_v2.fill`)."""
        e = x.scalars
        rows = TeamRows(e.est, e.velocity, e.leader, group_sizes(e.leader), x.waypoint, x.plan_progress, x.visited)
        fill(obs, slices, self.route_facts, rows, self.neighbours)

    def done_column(self, visited: np.ndarray) -> np.ndarray:
        """``route_done`` ``(K, N)`` float: 1 once every KPOI of the robot's own route is visited."""
        return target_kpois(self.route_facts, visited)[1].astype(float)

    def state(self, env: Any) -> np.ndarray:
        return critic_state.global_state(env, self.route_facts, self.state_space)

    def route_done(self, env: Any) -> np.ndarray:
        return target_kpois(self.route_facts, env.progress.visited[None])[1][0]


FEATURE_SETS: dict[int, type[CoreFeatures]] = {1: CoreFeatures, 2: RouteFeatures}
"""Every observation version's feature set, by ``observation.version``."""


def feature_set(version: int) -> type[CoreFeatures]:
    """The feature set of observation ``version`` (the schema admits only the keys of :data:`FEATURE_SETS`)."""
    return FEATURE_SETS[version]
