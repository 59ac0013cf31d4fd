"""The stepper's score phase (part 1b) for ``K`` worlds of one scenario at once.

After the act phase has moved every world, :func:`score` tracks the mission, splits and hands over
(Alg. 1), scores and records each world, on ``(K, N)`` blocks:

* the pose estimates: a copy of the act phase's estimator rows (:class:`~parcover_env.sim.act_phase.Acted`);
* route progress, KPOI visits, goals and the route length to go: one compiled call for all worlds
  (:func:`parcover_env.scenarios.progress.step_many`) on the trackers' arrays as rows of ``(K, ...)``
  blocks (:func:`score_blocks`), updated in place;
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
(:func:`score_blocks`, :class:`~parcover_env.world.batching.SharedRows`): the compiled calls update every
world in place, with no gather and no write-back; a copy or pickle of a world holds plain arrays,
and a world reset since is adopted again. So worlds stay independent (deepcopy, pickle) and the
ParallelEnv is the ``K = 1`` call; world ``k`` gets bit for bit what it would alone
(``tests/envs/test_batched.py``, ``tests/envs/test_score_phase.py``).
No random numbers are drawn here.
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import attrgetter
from typing import Any, NamedTuple

import numpy as np

from parcover_env.localization.estimator import ActRows
from parcover_env.mission.metrics import SUMS, record_steps
from parcover_env.mission.rewards import RewardInputs, inputs_needed, own_visits, reward_terms, sigma_major, touching
from parcover_env.mission.team import TEAM_ROWS, count_waypoints_many, update_teams
from parcover_env.scenarios.progress import STATE, step_many
from parcover_env.scenarios.progress_kernel import TrackerRows
from parcover_env.sim.act_phase import Acted
from parcover_env.sim.contract import ScoreState, StepWorld
from parcover_env.world.batching import SharedRows

__all__ = ["ScoreState", "Scores", "score", "gather", "rows", "HELD", "PARTS", "ScoreBlocks", "ScoreGroup",
           "score_blocks"]


def gather(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """The ``(K, ...)`` block of ``K`` worlds' arrays of one shape, a copy (never a world's own array)."""
    return np.array(arrays)


def rows(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """The ``(K, ...)`` block of ``K`` worlds' arrays of one shape, to read only: for ``K = 1`` a
    view of the world's array (no copy), else a copy."""
    return arrays[0][None] if len(arrays) == 1 else np.array(arrays)


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


def score(worlds: Sequence[StepWorld], acted: Acted) -> Scores:
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


HELD = ("remaining", "wall", "robot")
"""The arrays of a world's ``score_state`` (:class:`ScoreState`)."""

PARTS: dict[str, tuple[str, tuple[str, ...]]] = {
    "progress": ("progress", STATE),
    "team": ("team", TEAM_ROWS),
    "metrics": ("metrics", SUMS),
    "held": ("score_state", HELD),
}
"""Each part of a world the score phase updates: the world's attribute holding the owner, and the
owner's arrays."""


class ScoreBlocks(NamedTuple):
    """The :data:`PARTS` of ``K`` worlds, each a dict ``{array name: (K, ...) block}``."""

    progress: dict[str, np.ndarray]
    team: dict[str, np.ndarray]
    metrics: dict[str, np.ndarray]
    held: dict[str, np.ndarray]


def _owners(worlds: Sequence[StepWorld], attr: str) -> list[Any]:
    return list(map(attrgetter(attr), worlds))


class ScoreGroup:
    """The blocks of ``K > 1`` worlds of one scenario.

    Each world's route tracker, team, metrics and score state make their arrays (:data:`PARTS`) once
    and never rebind them: every step, split and record writes into them in place. So for one world
    the blocks are simply ``(1, ...)`` views of its own arrays. For ``K > 1`` worlds a group owns a
    ``(K, ...)`` block per array and the worlds' arrays are views of their rows
    (:class:`~parcover_env.world.batching.SharedRows`: an owner is adopted by copying its values in and
    handing it the row's views). Each world records the group it was attached to last
    (``score_group``, which the env leaves out of its copies and pickles); a group stepped again with
    the very worlds and owners it holds has nothing to attach, and a world reset since (new owners) or
    attached to another group since is adopted again."""

    def __init__(self, worlds: Sequence[StepWorld]):
        self.rows = {part: SharedRows(len(worlds), names, getattr(worlds[0], attr))
                     for part, (attr, names) in PARTS.items()}
        self.blocks = ScoreBlocks(**{part: rows.blocks for part, rows in self.rows.items()})

    @property
    def size(self) -> int:
        """The number of worlds ``K``."""
        return self.rows["team"].size

    def fits(self, worlds: Sequence[StepWorld]) -> bool:
        """True if these blocks can hold ``worlds`` (as many, shaped as these)."""
        return all(rows.fits(len(worlds), getattr(worlds[0], PARTS[part][0])) for part, rows in self.rows.items())

    def holds(self, worlds: Sequence[StepWorld]) -> bool:
        """True if ``worlds`` were attached to this group last, in this order, with the owners they hold now."""
        return ([getattr(w, "score_group", None) for w in worlds].count(self) == len(worlds)
                and all(rows.owners == _owners(worlds, PARTS[part][0]) for part, rows in self.rows.items()))

    def attach(self, worlds: Sequence[StepWorld]) -> None:
        """Make world ``k``'s owners those of row ``k`` (:meth:`SharedRows.attach`) and this group theirs."""
        for part, rows in self.rows.items():
            rows.attach(_owners(worlds, PARTS[part][0]))
        for w in worlds:
            w.score_group = self


def score_blocks(worlds: Sequence[StepWorld]) -> ScoreBlocks:
    """The :data:`PARTS` of the ``K`` worlds as ``(K, ...)`` blocks that the worlds' arrays are rows of:
    for one world, views of its own arrays; for more, the blocks of their :class:`ScoreGroup` (the
    group the first world was attached to, if it fits; else a new one), every world attached."""
    if len(worlds) == 1:
        w = worlds[0]
        return ScoreBlocks(**{part: {name: getattr(getattr(w, attr), name)[None] for name in names}
                              for part, (attr, names) in PARTS.items()})
    group = getattr(worlds[0], "score_group", None)
    if group is None or not group.fits(worlds):
        group = ScoreGroup(worlds)
    if not group.holds(worlds):
        group.attach(worlds)
    return group.blocks
