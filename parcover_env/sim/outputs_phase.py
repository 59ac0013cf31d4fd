"""The stepper's outputs phase (part 3) for ``K`` worlds of one scenario at once: the rewards,
terminations, truncations and infos of every agent slot (:func:`slot_outputs`, what a VecEnv reads);
a world's PettingZoo ``(rewards, terminations, truncations, infos)`` dicts are :func:`agent_dicts` of them.

Rewards, estimate errors and the other per-agent info values are computed as ``(K, N)`` arrays and
turned into Python floats once (``tolist``); each agent's info is a copy of its world's template
(the reward terms, the ``metrics/*`` entries, ...) updated with its own values, the key order fixed:
``reward_<term>`` (the world's terms order), ``metrics/*``, ``pose_error``, ``heading_error``, then
``sonar_fix`` (with ``observation.scan``), then the feature set's own values (``features.info``:
version 2's ``route_done``). The ``metrics/*`` entries
are the zeros of :meth:`~parcover_env.mission.metrics.EpisodeMetrics.flat` (a fresh ``path_lengths``
array per world) except in a world whose episode ends this step, where they are its metrics.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from parcover_env.geometry import wrap_angle
from parcover_env.mission.metrics import EpisodeMetrics
from parcover_env.mission.rewards import TEAM_TERMS
from parcover_env.sim.contract import StepWorld
from parcover_env.sim.score_phase import Scores, rows

__all__ = ["SlotOutputs", "slot_outputs", "agent_dicts", "infos", "slot_infos"]


class SlotOutputs(NamedTuple):
    """Part 3 of ``K`` worlds of ``N`` agents each, by agent slot (world ``k``'s agents are slots
    ``k N ... (k + 1) N - 1``)."""

    rewards: np.ndarray
    """``(K, N)`` every agent's reward (its terms summed in the worlds' terms order)."""
    terminated: list[bool]
    """Per world: every KPOI visited this step (all its agents end)."""
    truncated: list[bool]
    """Per world: the step limit reached, not terminated."""
    infos: list[dict]
    """The ``K N`` agents' infos, world by world (:func:`slot_infos`)."""


def slot_outputs(worlds: Sequence[StepWorld], true: np.ndarray, scores: Scores, *, active: bool = False) -> SlotOutputs:
    """Part 3 of the ``K`` worlds at true poses ``(K, N, 3)`` with the score phase's ``scores``, by
    agent slot (a world's agents are cleared when its episode ends); ``active``: every info has
    ``"active": True`` (a VecEnv's agent slots)."""
    first = worlds[0]
    terms = scores.terms
    total = 0
    for t in first.terms:  # summed in terms order, as sum() over the terms of each agent would
        total = total + terms[t]
    max_steps = first.scenario.episode.max_steps
    done = scores.visited.all(axis=1).tolist()
    truncated = [w.steps >= max_steps and not d for w, d in zip(worlds, done, strict=True)]
    ended = [d or t for d, t in zip(done, truncated, strict=True)]
    flat = slot_infos(worlds, true, [terms[t] for t in first.terms], ended, estimates=scores.estimates,
                      visited=scores.visited, active=active, team_terms=TEAM_TERMS)
    for w, e in zip(worlds, ended, strict=True):
        if e:
            w.agents = []
    return SlotOutputs(total, done, truncated, flat)


def agent_dicts(names: Sequence[str], out: SlotOutputs, k: int = 0) -> tuple[dict, dict, dict, dict]:
    """World ``k``'s PettingZoo ``(rewards, terminations, truncations, infos)`` dicts of ``out`` by
    agent name (``names``: the world's agents in slot order)."""
    n = len(names)
    return (dict(zip(names, out.rewards[k].tolist(), strict=True)), dict.fromkeys(names, out.terminated[k]),
            dict.fromkeys(names, out.truncated[k]), dict(zip(names, out.infos[k * n:(k + 1) * n], strict=True)))


def infos(worlds: Sequence[StepWorld], true: np.ndarray, terms: Sequence[np.ndarray], ended: Sequence[bool], *,
          estimates: np.ndarray | None = None, visited: np.ndarray | None = None,
          active: bool = False, team_terms: Sequence[str] = ()) -> list[dict[str, dict]]:
    """``info[agent]`` of every agent of the ``K`` worlds: :func:`slot_infos` by world and agent name."""
    flat = slot_infos(worlds, true, terms, ended, estimates=estimates, visited=visited, active=active,
                      team_terms=team_terms)
    n = worlds[0].n_robots
    return [dict(zip(w.agents, flat[k * n:(k + 1) * n], strict=True)) for k, w in enumerate(worlds)]


def slot_infos(worlds: Sequence[StepWorld], true: np.ndarray, terms: Sequence[np.ndarray], ended: Sequence[bool], *,
               estimates: np.ndarray | None = None, visited: np.ndarray | None = None,
               active: bool = False, team_terms: Sequence[str] = ()) -> list[dict]:
    """The info of every agent of the ``K`` worlds, world by world (``K N`` dicts; see the module
    docstring): ``terms[i]`` the values ``(K, N)`` of term ``i`` (the worlds' terms order);
    ``ended[k]``: world ``k``'s episode ends this step (its ``metrics/*`` entries are its metrics).
    ``estimates (K, N, 3)``, ``visited (K, M)``: the worlds' pose estimates and visited KPOIs if already
    gathered (read from the worlds if not); ``active``: every info also has ``"active": True`` (its
    last key; a VecEnv's agent slots); ``team_terms``: the terms whose values are one per world (the
    same for all its agents, as :data:`~parcover_env.mission.rewards.TEAM_TERMS` are): their first column is read.

    Each column becomes Python floats once for all worlds (one ``tolist``); each agent's dict is a
    copy of its world's template updated with its row."""
    first = worlds[0]
    n = first.n_robots
    est = rows([w.estimate for w in worlds]) if estimates is None else estimates
    d = est[..., :2] - true[..., :2]
    own = first.features.info  # the info values of the worlds' feature set (version 2's ``route_done``)
    base, reward_keys, keys = _template(tuple(first.terms), tuple(key for key, _ in own) if own else (),
                                        first.scanner is not None, active)
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
    if own:
        visited = rows([w.progress.visited for w in worlds]) if visited is None else visited
        columns += [column(visited) for _, column in own]
    values = np.stack(columns, axis=-1).tolist()  # [world][agent][column]
    team_values = np.stack(team_columns, axis=-1).tolist() if team_columns else [()] * len(worlds)
    flat = []
    for w, e, agents, team in zip(worlds, ended, values, team_values, strict=True):
        template = dict(base)
        template["metrics/path_lengths"] = np.zeros(n)
        if e:  # the step that ends the episode: its metrics
            template.update(w.metrics.flat(ended=True))
        template.update(zip(team_keys, team, strict=True))  # one value for all the world's agents
        for row in agents:
            info = template.copy()
            info.update(zip(keys, row, strict=True))
            flat.append(info)
    return flat


@functools.lru_cache(maxsize=16)
def _template(terms: tuple[str, ...], own: tuple[str, ...], sonar_fix: bool,
              active: bool) -> tuple[dict, tuple[str, ...], tuple[str, ...]]:
    """The info of an agent before its own values (zeros; ``metrics/path_lengths`` to be replaced by a
    fresh array), the keys of the reward terms, and the keys of the agent's other values in the order
    :func:`slot_infos` builds their columns (``own``: the keys of the feature set's own values). Read only: copy it."""
    reward_keys = tuple(f"reward_{t}" for t in terms)
    keys = ("pose_error", "heading_error")
    base = dict.fromkeys(reward_keys, 0.0)
    base.update(EpisodeMetrics(0, 0, 0.0, 0.0).flat(ended=False))
    base["pose_error"] = base["heading_error"] = 0.0
    if sonar_fix:
        base["sonar_fix"] = 0.0
        keys = (*keys, "sonar_fix")
    for key in own:  # the feature set's own values
        base[key] = 0.0
        keys = (*keys, key)
    if active:
        base["active"] = True
    return base, reward_keys, keys
