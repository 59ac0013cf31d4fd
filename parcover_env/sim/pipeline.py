"""The public stepper: one env step over ``K`` worlds of one scenario (``K = 1``: the ParallelEnv).

``ParallelCoverageEnv``, the batched worlds (:mod:`parcover_env.envs.batched`) and the single-robot
env all step through here, so the rules are written once:

1. **act** (all worlds at once, :func:`parcover_env.sim.act_phase.act`): act, integrate the
   physics, update the pose estimator (odometry, fixes); **score** (all worlds at once,
   :func:`parcover_env.sim.score_phase.score`): track the mission, hand over at splits (Alg. 1),
   score, record;
2. **sense and observe** (:func:`observe`, all worlds at once): one :class:`SensingState` of every
   world; the follower cameras first, then one compiled pass (the layout's) writes every non-sensor
   entry of the observation spec of every world, the worlds' feature set writes the entries it owns
   (``features.fills``: version 2's ``route`` and ``teammates``), and every ``sensor`` entry of the
   spec is filled by its sensor's ``sense`` for all worlds in one call; clipped into the bounds.
   World ``k`` draws from its own generator in the order a single world would, so it is bit for bit
   a separate env;
3. **outputs** (all worlds at once, :func:`parcover_env.sim.outputs_phase.slot_outputs`): rewards,
   terminations, truncations, infos by agent slot, what a VecEnv reads (a world's PettingZoo dicts:
   :func:`parcover_env.sim.outputs_phase.agent_dicts`);
4. a world whose agents are all done is reset by the caller (auto-reset); what a vectorized or
   single-agent view adds to an agent's info is :mod:`parcover_env.envs.slots`.

The stepper reads the worlds through the names of its contract only
(:class:`~parcover_env.sim.contract.StepWorld`: ``team``, ``estimator``, ``progress``, ``layout``,
``features``, ``sensors``, ``camera``, ``np_random``, ...).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from parcover_env.mission.team import CameraView
from parcover_env.scenarios.progress import goals_many
from parcover_env.sensors.base import SensingState
from parcover_env.sim import act_phase, outputs_phase, score_phase
from parcover_env.sim.contract import ObsInputs, ScalarInputs, StepWorld
from parcover_env.sim.outputs_phase import SlotOutputs
from parcover_env.sim.score_phase import Scores, gather, rows

__all__ = ["ScalarInputs", "ObsInputs", "sensing_state", "observe", "step"]


def sensing_state(worlds: Sequence[StepWorld], true: np.ndarray, predecessor: np.ndarray | None = None) -> SensingState:
    """What the sensors read: ``true (K, N, 3)`` poses of the worlds, their shared walls and radius,
    and who follows whom in each world (``predecessor (K, N)``, gathered from the teams if not given)."""
    first = worlds[0]
    if predecessor is None:
        predecessor = rows([w.team.predecessor for w in worlds])
    return SensingState(true, first.map.segments, float(first.scenario.robot.radius), predecessor)


def observe(worlds: Sequence[StepWorld], true: np.ndarray, scores: Scores | None = None) -> np.ndarray:
    """Observations ``(K, N, D)`` float32 of every robot of the ``K`` worlds at true poses ``(K, N, 3)``
    (``scores``: this step's score phase, whose goal points, estimates, visits, team rows and estimator
    rows it reads instead of gathering them again). Sets each world's ``camera_views`` and
    ``camera_index`` (the cameras' measurements of all worlds, blocks, and its row: its ``camera_view``,
    which Alg. 1's next hand-over uses)."""
    first = worlds[0]
    if scores is None:  # at reset: the worlds' state as it is
        teams = [w.team for w in worlds]
        team = {"leader": rows([t.leader for t in teams]), "slot": rows([t.slot for t in teams]),
                "predecessor": rows([t.predecessor for t in teams])}
    else:  # this step's blocks
        team = scores.team
    # a split writes the teams' arrays in place: the camera view keeps a copy of what it was measured against
    team = {**team, "predecessor": team["predecessor"].copy()}
    state = sensing_state(worlds, true, team["predecessor"])
    rngs = [w.np_random for w in worlds]
    seen = first.camera.measure_many(true, state.predecessor, state.segments, rngs)
    obs = np.zeros((len(worlds), state.n_robots, first.layout.size), dtype=np.float32)
    if scores is None:
        goals, est, visited = (goals_many([w.progress for w in worlds])[0], gather([w.estimate for w in worlds]),
                               rows([w.progress.visited for w in worlds]))
    else:
        goals, est, visited = scores.goals, scores.estimates, scores.visited
    if scores is None:
        estimators = [w.estimator for w in worlds]
        velocity, fix_age = rows([e.velocity for e in estimators]), rows([e.fix_age for e in estimators])
        covariance = rows([e.covariance for e in estimators])
    else:
        act = scores.act
        velocity, fix_age = act.estimators.blocks["velocity"], act.estimators.blocks["fix_age"]
        covariance = act.odometry.blocks["covariance"]
    rel_xy, rel_heading, visible = seen
    views = CameraView(state.predecessor, seen, est)  # of all worlds; world k reads its row (camera_view)
    for k, w in enumerate(worlds):
        w.camera_views, w.camera_index = views, k
    scalars = ScalarInputs(est, velocity, team["leader"], team["slot"], fix_age, covariance, goals, rel_xy, rel_heading,
                           visible, visited.sum(axis=1) / visited.shape[1],
                           np.array([w.steps for w in worlds]) / first.scenario.episode.max_steps)
    first.layout.fill_scalars_many(obs, scalars)
    if first.scanner is not None:  # the ``scan`` entries of the spec
        for k, w in enumerate(worlds):
            for name, values in w.localization_entries().items():
                obs[k][:, w.layout.slices[name]] = values[:, None]
    fills = first.features.fills  # the entries the worlds' feature set fills itself (version 2's route, teammates)
    if fills:
        if scores is None:
            waypoint, plan_progress = rows([w.progress.waypoint for w in worlds]), rows([w.progress.plan_progress
                                                                                       for w in worlds])
        else:  # this step's blocks
            waypoint, plan_progress = scores.track.waypoint, scores.track.progress - first.progress.offsets
        inputs = ObsInputs(scalars, waypoint, plan_progress, visited)
        for fill in fills:
            fill(obs, first.layout.slices, inputs)
    for name, sensor in first.sensors.items():  # every sensor entry of the spec, all worlds in one call
        if sensor is not None:
            obs[..., first.layout.slices[name]] = sensor.sense(state, rngs)
    first.layout.clip(obs)
    return obs


def step(worlds: Sequence[StepWorld], actions: Sequence[dict[str, Any]] | np.ndarray, *,
         active: bool = False) -> tuple[np.ndarray, SlotOutputs]:
    """One step of every world (``actions[k]``: world ``k``'s action dict, or one array ``(K, N, A)``
    of every world's agents' actions in agent order): act, score, observe, outputs. Returns the
    observations ``(K, N, D)`` and the outputs by agent slot (:class:`SlotOutputs`; ``active``: every
    info with ``"active": True``, as a VecEnv's slots have it); a world's PettingZoo dicts are
    :func:`~parcover_env.sim.outputs_phase.agent_dicts` of them."""
    acted = act_phase.act(worlds, actions)
    scores = score_phase.score(worlds, acted)
    obs = observe(worlds, acted.true, scores)
    return obs, outputs_phase.slot_outputs(worlds, acted.true, scores, active=active)
