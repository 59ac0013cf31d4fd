"""The stepper's score phase (part 1b) for ``K`` worlds of one scenario at once.

After the act phase has moved every world, :func:`score` tracks the mission, splits and hands over
(Alg. 1), scores and records each world, on ``(K, N)`` blocks:

* the pose estimates: a copy of the act phase's estimator rows (:class:`~parcover_env.sim.act_phase.Acted`);
* route progress, KPOI visits, goals and the route length to go: one compiled call for all worlds
  (:func:`parcover_env.scenarios.progress.step_many`) on the trackers' arrays as rows of ``(K, ...)``
  blocks (:func:`parcover_env.sim.rows.score_blocks`), updated in place;
* the team update on the teams' arrays as rows of blocks too
  (:data:`~parcover_env.mission.team.TEAM_ROWS`): waypoint messages counted over ``(K, N)``; only the
  worlds where a leader may have reached its TP run the (rare) Python split
  (:func:`parcover_env.mission.team.update_teams`), which writes its team's arrays in place;
* the reward terms as ``(K, N)`` arrays (:func:`parcover_env.mission.rewards.reward_terms`), returned
  in a :class:`Scores` for the outputs phase (with the goal points, the team rows and the estimator
  rows, for the observations);
* the metrics of all worlds in one call (:func:`parcover_env.mission.metrics.record_steps`), their sums
  rows of blocks too.

The worlds' trackers, teams, metrics and :class:`ScoreState` keep their own arrays (never rebound),
which are views of row ``k`` of ``(K, ...)`` blocks while they are scored together
(:mod:`parcover_env.sim.rows`): the compiled calls update every world in place, with no gather
and no write-back; a copy or pickle of a world holds plain arrays, and a world reset since is
adopted again. So worlds stay
independent (deepcopy, pickle) and the ParallelEnv is the ``K = 1`` call; world ``k`` gets bit for
bit what it would alone (``tests/envs/test_batched.py``, ``tests/envs/test_score_phase.py``).
No random numbers are drawn here.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from parcover_env.mission.metrics import record_steps
from parcover_env.mission.rewards import RewardInputs, inputs_needed, own_visits, reward_terms, sigma_major, touching
from parcover_env.mission.team import count_waypoints_many, update_teams
from parcover_env.scenarios.progress import step_many
from parcover_env.scenarios.progress_kernel import TrackerRows
from parcover_env.sim.rows import ActRows, score_blocks

if TYPE_CHECKING:  # an annotation only: act_phase imports the estimator, whose package imports the env
    from parcover_env.sim.act_phase import Acted

__all__ = ["ScoreState", "Scores", "score", "gather", "rows"]


def gather(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """The ``(K, ...)`` block of ``K`` worlds' arrays of one shape, a copy (never a world's own array)."""
    return np.array(arrays)


def rows(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """The ``(K, ...)`` block of ``K`` worlds' arrays of one shape, to read only: for ``K = 1`` a
    view of the world's array (no copy), else a copy."""
    return arrays[0][None] if len(arrays) == 1 else np.array(arrays)


class ScoreState:
    """What scoring carries over from one step of a world to the next: arrays made here and never
    rebound (the score phase writes them in place, as rows of ``(K, ...)`` blocks when the world is
    scored with others: :func:`~parcover_env.sim.rows.score_blocks`)."""

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


class Scores(NamedTuple):
    """What the score phase hands to the outputs phase."""

    terms: dict[str, np.ndarray]
    """This step's reward terms ``(K, N)`` by name (every world's terms, in its summing order)."""
    goals: np.ndarray
    """The robots' lookahead goal points ``(K, N, 2)`` after this step's progress (the observations')."""
    estimates: np.ndarray
    """The pose estimates ``(K, N, 3)`` of this step (a copy; scoring does not move them)."""
    visited: np.ndarray
    """The KPOIs visited ``(K, M)`` after this step's progress (to read only)."""
    team: dict[str, np.ndarray]
    """The teams' :data:`~parcover_env.mission.team.TEAM_ROWS` blocks ``(K, N, ...)`` after this step's
    splits (to read only, this step: the rows of the worlds' teams)."""
    act: ActRows
    """The act phase's shared rows of the worlds' pose estimators, every world's attached (to read
    only, this step)."""
    track: TrackerRows
    """The route trackers' :data:`~parcover_env.scenarios.progress.STATE` blocks after this step's
    progress (to read only, this step)."""


def score(worlds: Sequence[Any], acted: Acted) -> Scores:
    """Part 1b of the ``K`` worlds after the act phase (``acted``: the true poses before and after the
    step ``(K, N, 3)``, the estimators' rows; see the module docstring); returns their reward terms and
    goal points."""
    first = worlds[0]
    s = first.scenario
    before, true, act = acted
    trackers, teams = [w.progress for w in worlds], [w.team for w in worlds]
    est = act.odometry.blocks["estimate"].copy()
    blocks = score_blocks(worlds)  # the worlds' arrays as rows of (K, ...) blocks, updated in place
    state = TrackerRows(**blocks.progress)
    needs = inputs_needed(first.terms)  # the optional inputs of the worlds' reward terms
    was = state.visited.copy() if "own_new" in needs else None
    times = [w.world.time for w in worlds]
    true_xy = np.ascontiguousarray(true[..., :2])
    n_new, goals, remaining = step_many(trackers, true_xy, est[..., :2], times, state)
    velocity = (true_xy - before[..., :2]) / s.physics.control_dt
    team = blocks.team  # a split writes them in place
    count_waypoints_many(teams, state.advanced, team["leader"])
    update_teams(teams, [w.kinects for w in worlds], est, state.progress - first.progress.offsets,
                 lambda k: worlds[k].camera_view, tp=team["tp_ahead"])
    own = None
    visited = state.visited
    if "own_new" in needs:
        own = own_visits(visited & ~was, state.visitor, first.kpoi_owner, first.n_robots)
    held = blocks.held  # the last step's, updated in place
    gained = held["remaining"] - remaining
    wall, robot = gather([w.world.wall_contacts for w in worlds]), gather([w.world.robot_contacts for w in worlds])
    new_wall, new_robot = wall - held["wall"], robot - held["robot"]
    held["remaining"][...], held["wall"][...], held["robot"][...] = remaining, wall, robot
    for w, v in zip(worlds, velocity, strict=True):  # row views of the block, as the worlds' own
        w.true_velocity = v
    touch = None
    if "touch" in needs:
        gap = s.rewards.contact_gap
        touch = np.array([touching(xy, w.world.map.segments, w.world.radius, gap)
                          for w, xy in zip(worlds, true_xy, strict=True)])
    sigma = None
    if "sigma" in needs:  # of the estimates' covariances after this step's fixes
        sigma = sigma_major(act.odometry.blocks["covariance"])
    terms = reward_terms(s.rewards, first.terms, RewardInputs(n_new, gained, new_wall + new_robot, own, touch, sigma))
    record_steps([w.metrics for w in worlds], before, true, times=times, progress=trackers, estimates=est,
                 new_contacts=(new_wall, new_robot), teams=teams, formation=s.formation, kinects=first.kinects,
                 control_dt=s.physics.control_dt, visits=(state.visited, state.visit_time), team_rows=team,
                 sums=blocks.metrics)
    for k, w in enumerate(worlds):
        if w.render_mode is not None:
            for trail, p in zip(w.trails, true[k], strict=True):
                trail.append(p[:2].copy())
    return Scores(terms, goals, est, visited, team, act, state)

