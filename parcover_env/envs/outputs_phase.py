"""The stepper's outputs phase (part 3) for ``K`` worlds of one scenario at once: each world's
PettingZoo ``(rewards, terminations, truncations, infos)`` dicts.

Rewards, estimate errors and the other per-agent info values are computed as ``(K, N)`` arrays and
turned into Python floats once (``tolist``); each agent's info is a copy of its world's template
(the reward terms, the ``metrics/*`` entries, ...) updated with its own values, the key order fixed:
``reward_<term>`` (the world's terms order), ``metrics/*``, ``pose_error``, ``heading_error``, then
``sonar_fix`` (with ``observation.scan``), then ``route_done`` (version 2). The ``metrics/*`` entries
are the zeros of :meth:`~parcover_env.envs.metrics.EpisodeMetrics.flat` (a fresh ``path_lengths``
array per world) except in a world whose episode ends this step, where they are its metrics.
"""

from __future__ import annotations

import functools
from collections import deque
from collections.abc import Sequence
from itertools import repeat
from operator import setitem
from typing import Any

import numpy as np

from parcover_env.envs.metrics import EpisodeMetrics
from parcover_env.envs.obs_v2 import target_kpois
from parcover_env.envs.rewards import TEAM_TERMS
from parcover_env.envs.score_phase import Scores, rows
from parcover_env.geometry import wrap_angle

__all__ = ["outputs", "infos"]


def outputs(worlds: Sequence[Any], true: np.ndarray, scores: Scores, *,
            active: bool = False) -> list[tuple[dict, dict, dict, dict]]:
    """Part 3 of the ``K`` worlds at true poses ``(K, N, 3)`` with the score phase's ``scores``:
    ``(rewards, terminations, truncations, infos)`` per world (a world's agents are cleared when
    its episode ends); ``active``: every info has ``"active": True`` (a VecEnv's agent slots)."""
    first = worlds[0]
    terms = scores.terms
    total = 0
    for t in first.terms:  # summed in terms order, as sum() over the terms of each agent would
        total = total + terms[t]
    max_steps = first.scenario.episode.max_steps
    done = scores.visited.all(axis=1).tolist()
    truncated = [w.steps >= max_steps and not d for w, d in zip(worlds, done, strict=True)]
    ended = [d or t for d, t in zip(done, truncated, strict=True)]
    all_infos = infos(worlds, true, [terms[t] for t in first.terms], ended, estimates=scores.estimates,
                      visited=scores.visited, active=active, team_terms=TEAM_TERMS)
    out = []
    for w, rewards, info, d, t, e in zip(worlds, total.tolist(), all_infos, done, truncated, ended, strict=True):
        agents = w.agents
        out.append((dict(zip(agents, rewards, strict=True)), dict.fromkeys(agents, d), dict.fromkeys(agents, t), info))
        if e:
            w.agents = []
    return out


def infos(worlds: Sequence[Any], true: np.ndarray, terms: Sequence[np.ndarray], ended: Sequence[bool], *,
          estimates: np.ndarray | None = None, visited: np.ndarray | None = None,
          active: bool = False, team_terms: Sequence[str] = ()) -> list[dict[str, dict]]:
    """``info[agent]`` of every agent of the ``K`` worlds (see the module docstring): ``terms[i]`` the
    values ``(K, N)`` of term ``i`` (the worlds' terms order); ``ended[k]``: world ``k``'s episode
    ends this step (its ``metrics/*`` entries are its metrics). ``estimates (K, N, 3)``, ``visited
    (K, M)``: the worlds' pose estimates and visited KPOIs if already gathered (read from the worlds if not);
    ``active``: every info also has ``"active": True`` (its last key; a VecEnv's agent slots);
    ``team_terms``: the terms whose values are one per world (the same for all its agents, as
    :data:`~parcover_env.envs.rewards.TEAM_TERMS` are): their first column is read.

    Built with the fewest Python operations: each per-agent column becomes Python floats once for
    all worlds (one ``tolist``), every agent's dict is a C-level copy of its world's template (which
    holds the ``team_terms``), and each other column is written into all ``K N`` dicts by one C-level
    ``map`` (no loop per agent)."""
    first = worlds[0]
    n = first.n_robots
    est = rows([w.estimate for w in worlds]) if estimates is None else estimates
    d = est[..., :2] - true[..., :2]
    base, reward_keys, keys = _template(tuple(first.terms), first.version == 2, first.scanner is not None, active)
    columns, agent_keys, team_keys, team_columns = [], [], [], []
    for name, key, term in zip(first.terms, reward_keys, terms, strict=True):
        c = np.asarray(term, dtype=float)
        if name in team_terms:  # one value per world: set in its template
            team_keys.append(key)
            team_columns.append(c[:, 0])
        else:
            agent_keys.append(key)
            columns.append(c)
    keys = (*agent_keys, *keys)
    columns += [np.hypot(d[..., 0], d[..., 1]), np.abs(wrap_angle(est[..., 2] - true[..., 2]))]
    if first.scanner is not None:
        columns.append(rows([w.scanner.outcome for w in worlds]))
    if first.version == 2:
        visited = rows([w.progress.visited for w in worlds]) if visited is None else visited
        columns.append(target_kpois(first.route_facts, visited)[1].astype(float))
    team_values = zip(*(c.tolist() for c in team_columns)) if team_keys else repeat((), len(worlds))
    out, flat = [], []
    for w, e, values in zip(worlds, ended, team_values, strict=True):
        template = base.copy()
        if e:
            template.update(w.metrics.flat(ended=True))
        else:
            template[_PATH_KEY] = np.zeros(n)
        template.update(zip(team_keys, values))  # the team terms: one value for all the world's agents
        world_infos = dict(zip(w.agents, map(dict.copy, repeat(template, n)), strict=True))
        out.append(world_infos)
        flat += world_infos.values()
    for key, column in zip(keys, columns, strict=True):
        _consume(map(setitem, flat, repeat(key), column.reshape(-1).tolist()))
    return out


_PATH_KEY = "metrics/path_lengths"
_consume = deque(maxlen=0).extend
"""Runs an iterator to its end at C speed, keeping nothing."""


@functools.lru_cache(maxsize=16)
def _template(terms: tuple[str, ...], route_done: bool, sonar_fix: bool,
              active: bool) -> tuple[dict, tuple[str, ...], tuple[str, ...]]:
    """The info of an agent before its own values (zeros; ``metrics/path_lengths`` to be replaced by a
    fresh array), the keys of the reward terms, and the keys of the agent's other values in the order
    :func:`infos` builds their columns. Read only: copy it."""
    reward_keys = tuple(f"reward_{t}" for t in terms)
    keys = ("pose_error", "heading_error")
    base = dict.fromkeys(reward_keys, 0.0)
    base.update(EpisodeMetrics(0, 0, 0.0, 0.0).flat(ended=False))
    base["pose_error"] = base["heading_error"] = 0.0
    if sonar_fix:
        base["sonar_fix"] = 0.0
        keys = (*keys, "sonar_fix")
    if route_done:
        base["route_done"] = 0.0
        keys = (*keys, "route_done")
    if active:
        base["active"] = True
    return base, reward_keys, keys
