"""The global state for centralized critics (``env.state()``), both versions.

Version 1 (:func:`state_v1`): true (x, y, cos, sin) and leader flag of every robot, the visited flag
of every KPOI, the elapsed time fraction: its length depends on the scenario.

Version 2: one fixed shape for every scenario, as tokens for a permutation-invariant critic.

``state()`` of an env with ``observation.version: 2`` is one flat float32 vector of
:data:`STATE_SIZE` values on every map: :data:`MAX_ROBOTS` robot tokens, then :data:`MAX_KPOIS`
KPOI tokens, then the global features; each token ends with its mask (1 = a real robot / KPOI,
0 = padding, all of whose features are 0). A critic embeds every token with one shared network and
pools over the tokens whose mask is 1 (attention or a GNN, as BenchMARL's GNN critic or MAT), so one
critic serves 1-16 robots and 1-32 KPOIs; :func:`state_tokens` reshapes a state (or a batch) into
those arrays and :func:`flat_state` back. Robot ``i``'s token is row ``i`` (agent order), so the
MAPPO paper's agent-specific state is the flat state plus the agent's index (or its own
observation). A scenario with more robots or KPOIs than the maxima raises a ``ConfigError`` when the
env is made. The tables below are generated from :data:`ROBOT_FEATURES` etc. (:func:`markdown_table`).

The critic sees what the policy cannot: true poses and each estimate's error, so it can value a
state by the pose error that decides which KPOIs will be missed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from parcover_env.config import Scenario
from parcover_env.envs.obs_spec import MAX_ROBOTS
from parcover_env.envs.obs_v2 import RouteFacts, target_kpois
from parcover_env.errors import ConfigError

__all__ = ["state_v1", "state_space_v1", "MAX_ROBOTS", "MAX_KPOIS", "Feature", "ROBOT_FEATURES", "KPOI_FEATURES",
           "GLOBAL_FEATURES", "STATE_SIZE",
           "StateTokens", "check_maxima", "state_space", "global_state", "state_tokens", "flat_state",
           "markdown_table"]

MAX_KPOIS = 32
"""Most KPOIs a version-2 env takes (KPOI tokens are padded to it)."""

Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class Feature:
    """One column of a token."""

    name: str
    unit: str
    bounds: Callable[[Scenario, Box], tuple[float, float]]
    bounds_doc: str
    meaning: str


def _x(s, b):
    return b[0], b[2]


def _y(s, b):
    return b[1], b[3]


def _unit(s, b):
    return -1.0, 1.0


def _flag(s, b):
    return 0.0, 1.0


def _speed(s, b):
    return -2.0 * s.robot.max_speed, 2.0 * s.robot.max_speed


def _error(s, b):
    d = float(np.hypot(b[2] - b[0], b[3] - b[1])) + 2.0
    return -d, d


ROBOT_FEATURES = (
    Feature("x", "m", _x, "map x", "true position x"),
    Feature("y", "m", _y, "map y", "true position y"),
    Feature("cos_theta", "-", _unit, "[-1, 1]", "cos of the true heading"),
    Feature("sin_theta", "-", _unit, "[-1, 1]", "sin of the true heading"),
    Feature("vx", "m/s", _speed, "+-2 max_speed", "true velocity x (world frame): last step's displacement / step"),
    Feature("vy", "m/s", _speed, "+-2 max_speed", "true velocity y (world frame)"),
    Feature("err_x", "m", _error, "+-(map diagonal + 2)", "pose estimate minus true position, x: how lost it is"),
    Feature("err_y", "m", _error, "+-(map diagonal + 2)", "pose estimate minus true position, y"),
    Feature("leader", "-", _flag, "[0, 1]", "1 if it leads its group (role), else 0"),
    Feature("progress", "-", _flag, "[0, 1]", "route progress: arc length reached / its route's length"),
    Feature("done", "-", _flag, "[0, 1]", "1 once every KPOI of its own route is visited (its ``done_mask``)"),
    Feature("mask", "-", _flag, "[0, 1]", "1 = a robot of this scenario, 0 = padding"),
)
"""Columns of a robot token."""
KPOI_FEATURES = (
    Feature("x", "m", _x, "map x", "KPOI position x"),
    Feature("y", "m", _y, "map y", "KPOI position y"),
    Feature("visited", "-", _flag, "[0, 1]", "1 once visited by any robot"),
    Feature("mask", "-", _flag, "[0, 1]", "1 = a KPOI of this scenario, 0 = padding"),
)
"""Columns of a KPOI token."""
GLOBAL_FEATURES = (
    Feature("time", "-", _flag, "[0, 1]", "fraction of the step limit elapsed"),
    Feature("kpois_visited", "-", _flag, "[0, 1]", "fraction of the scenario's KPOIs visited"),
)
"""The global features, after the tokens."""

_R, _K = MAX_ROBOTS * len(ROBOT_FEATURES), MAX_KPOIS * len(KPOI_FEATURES)
STATE_SIZE = _R + _K + len(GLOBAL_FEATURES)
"""Length of every version-2 state: 16 x 12 + 32 x 4 + 2 = 322."""


class StateTokens(NamedTuple):
    """A state (or a batch ``(..., STATE_SIZE)``) as tokens; features exclude the mask column."""

    robots: np.ndarray
    """``(..., MAX_ROBOTS, len(ROBOT_FEATURES) - 1)``."""
    robot_mask: np.ndarray
    """``(..., MAX_ROBOTS)`` bool."""
    kpois: np.ndarray
    """``(..., MAX_KPOIS, len(KPOI_FEATURES) - 1)``."""
    kpoi_mask: np.ndarray
    """``(..., MAX_KPOIS)`` bool."""
    globals: np.ndarray
    """``(..., len(GLOBAL_FEATURES))``."""


def state_v1(env: Any) -> np.ndarray:
    """Version 1's state of ``env`` (see the module docstring)."""
    true = env.true_poses()
    parts = [true[:, :2], np.cos(true[:, 2:3]), np.sin(true[:, 2:3]), env.team.leader[:, None]]
    robots = np.concatenate(parts, axis=1).ravel()
    t = [env.steps / env.scenario.episode.max_steps]
    return np.concatenate([robots, env.progress.visited.astype(float), t]).astype(np.float32)


def state_space_v1(bounds: Box, n_robots: int, n_kpois: int) -> spaces.Box:
    """Bounds of version 1's state: per robot x, y in the map box, cos, sin in [-1, 1], leader flag
    in [0, 1]; KPOI visited flags and the elapsed time fraction in [0, 1]."""
    x0, y0, x1, y1 = bounds
    robot_lo, robot_hi = [x0, y0, -1.0, -1.0, 0.0], [x1, y1, 1.0, 1.0, 1.0]
    low = np.array(robot_lo * n_robots + [0.0] * (n_kpois + 1), dtype=np.float32)
    high = np.array(robot_hi * n_robots + [1.0] * (n_kpois + 1), dtype=np.float32)
    return spaces.Box(low, high, dtype=np.float32)


def check_maxima(scenario: Scenario, n_robots: int) -> None:
    """Raise a ``ConfigError`` if the scenario has more robots or KPOIs than a version-2 state holds."""
    if n_robots > MAX_ROBOTS:
        raise ConfigError(scenario.source, "n_robots", f"observation version 2 takes at most {MAX_ROBOTS} robots "
                          f"(state() is padded to that), this scenario has {n_robots}")
    if len(scenario.kpois) > MAX_KPOIS:
        raise ConfigError(scenario.source, "kpois", f"observation version 2 takes at most {MAX_KPOIS} KPOIs "
                          f"(state() is padded to that), this scenario has {len(scenario.kpois)}")


def state_space(scenario: Scenario, box: Box) -> spaces.Box:
    """Bounds of the version-2 state on a map of bounds ``box``; shape ``(STATE_SIZE,)`` on every map
    (the bounds of x and y are the map's; padding, all zeros, lies inside them: the box holds 0)."""
    def rows(features, n):
        lo, hi = zip(*[f.bounds(scenario, box) for f in features], strict=True)
        return np.tile(lo, n), np.tile(hi, n)

    parts = [rows(ROBOT_FEATURES, MAX_ROBOTS), rows(KPOI_FEATURES, MAX_KPOIS), rows(GLOBAL_FEATURES, 1)]
    low = np.concatenate([p[0] for p in parts]).astype(np.float32)
    high = np.concatenate([p[1] for p in parts]).astype(np.float32)
    return spaces.Box(np.minimum(low, 0.0), np.maximum(high, 0.0), dtype=np.float32)


def global_state(env: Any, facts: RouteFacts, space: spaces.Box) -> np.ndarray:
    """The version-2 state of ``env`` (through its public names), clipped into ``space``."""
    true, est = env.true_poses(), env.estimate
    n, visited = len(true), env.progress.visited
    _, done = target_kpois(facts, visited[None])
    arc_end = env.progress.table.arc_end
    progress = np.where(arc_end > 0, env.progress.progress / np.where(arc_end > 0, arc_end, 1.0), 1.0)
    robots = np.zeros((MAX_ROBOTS, len(ROBOT_FEATURES)))
    robots[:n] = np.column_stack([true[:, :2], np.cos(true[:, 2]), np.sin(true[:, 2]), env.true_velocity,
                                  est[:, :2] - true[:, :2], env.team.leader, np.minimum(progress, 1.0), done[0],
                                  np.ones(n)])
    kpois = np.zeros((MAX_KPOIS, len(KPOI_FEATURES)))
    kpois[:len(visited)] = np.column_stack([facts.kpois, visited, np.ones(len(visited))])
    glob = [env.steps / env.scenario.episode.max_steps, np.count_nonzero(visited) / len(visited)]
    state = np.concatenate([robots.ravel(), kpois.ravel(), glob]).astype(np.float32)
    return np.clip(state, space.low, space.high)


def state_tokens(state: np.ndarray) -> StateTokens:
    """A flat version-2 state ``(..., STATE_SIZE)`` as :class:`StateTokens` (views where possible)."""
    state = np.asarray(state)
    if state.shape[-1] != STATE_SIZE:
        raise ValueError(f"a version-2 state has {STATE_SIZE} values, got shape {state.shape}")
    lead = state.shape[:-1]
    robots = state[..., :_R].reshape(*lead, MAX_ROBOTS, len(ROBOT_FEATURES))
    kpois = state[..., _R:_R + _K].reshape(*lead, MAX_KPOIS, len(KPOI_FEATURES))
    return StateTokens(robots[..., :-1], robots[..., -1] > 0.5, kpois[..., :-1], kpois[..., -1] > 0.5,
                       state[..., _R + _K:])


def flat_state(tokens: StateTokens) -> np.ndarray:
    """The inverse of :func:`state_tokens`: ``(..., STATE_SIZE)`` float32."""
    robots = np.concatenate([tokens.robots, tokens.robot_mask[..., None]], axis=-1)
    kpois = np.concatenate([tokens.kpois, tokens.kpoi_mask[..., None]], axis=-1)
    lead = tokens.globals.shape[:-1]
    return np.concatenate([robots.reshape(*lead, -1), kpois.reshape(*lead, -1), tokens.globals],
                          axis=-1).astype(np.float32)


def markdown_table() -> str:
    """The state layout table of ``ParallelCoverageEnv``'s docstring, generated from the features."""
    rows = ["| part | column | unit | bounds | meaning |", "|---|---|---|---|---|"]
    for part, features in ((f"robot token (x {MAX_ROBOTS})", ROBOT_FEATURES),
                           (f"KPOI token (x {MAX_KPOIS})", KPOI_FEATURES), ("global", GLOBAL_FEATURES)):
        rows += [f"| {part} | {f.name} | {f.unit} | {f.bounds_doc} | {f.meaning} |" for f in features]
    return "\n".join(rows)
