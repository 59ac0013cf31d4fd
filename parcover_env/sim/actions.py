"""Validation of the joint action: one clear ActionError, and never a state change, on bad input; the
common case (finite values of the right shape) checked, clipped and scaled in one compiled pass
(:func:`scaled_commands`, the same float operations as the numpy formulas: ``np.clip`` to [-1, 1], then
``v * max_speed`` and ``omega * max_turn_rate``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numba import njit

from parcover_env.errors import ActionError

__all__ = ["to_commands", "to_commands_all"]


def to_commands(actions: Mapping, agents: Sequence[str], max_speed: float,
                max_turn_rate: float, width: int = 2) -> np.ndarray:
    """Joint action ``{agent: (width,) in [-1, 1]}`` -> unicycle commands ``(N, width)``: (m/s, rad/s)
    and, with ``width = 3``, the ``scan`` component as given (clipped to [-1, 1]).

    Out-of-range values are clipped to [-1, 1] (documented behaviour); NaN/inf, a wrong shape, a
    non-real type (complex, bool, strings, None) and missing or unknown agents raise ActionError
    naming the agent.
    """
    out = _common_case(actions, agents, width)
    if out is None:
        out = _validated(actions, agents, width)
    np.minimum(np.maximum(out, -1.0, out=out), 1.0, out=out)  # clip (the values are finite here)
    out[:, 0] *= max_speed
    out[:, 1] *= max_turn_rate
    return out


def to_commands_all(actions: Sequence[Mapping] | np.ndarray, agents: Sequence[Sequence[str]], max_speed: float,
                    max_turn_rate: float, width: int = 2) -> np.ndarray:
    """:func:`to_commands` of ``K`` joint actions at once (``actions[k]`` for the agents
    ``agents[k]``, ``N`` each): commands ``(K, N, width)``. ``actions`` is either ``K`` action dicts
    or one array ``(K, N, width)`` whose row ``actions[k, i]`` is the action of ``agents[k][i]`` (the
    batched worlds pass their action block as it is). A float block of that shape with finite
    values, or ``K`` dicts that are each the common case, are taken into one array; otherwise each
    world's joint action is validated by :func:`to_commands` (the same ActionError, raised before
    any command is returned)."""
    k, n = len(agents), len(agents[0]) if agents else 0
    if isinstance(actions, np.ndarray):
        out = _scaled_block(actions, (k, n, width), max_speed, max_turn_rate)
        if out is not None:
            return out
        if actions.shape[:2] != (k, n):  # the uncommon case: each world's rows as its action dict, validated
            raise ActionError(f"actions: expected an array ({k}, {n}, {width}) (worlds, agents, action), "
                              f"got shape {actions.shape}")
        actions = [dict(zip(names, rows, strict=True)) for names, rows in zip(agents, actions, strict=True)]
    else:
        raw = _common_dicts(actions, agents, width)
        out = None if raw is None else _scaled_block(raw, raw.shape, max_speed, max_turn_rate)
        if out is not None:
            return out.reshape(k, n, width)
    # the uncommon case: each world's joint action checked on its own
    return np.stack([to_commands(a, names, max_speed, max_turn_rate, width)
                     for a, names in zip(actions, agents, strict=True)])


@njit(cache=True)
def scaled_commands(raw, max_speed, max_turn_rate, out):
    """Actions ``raw (m, width)`` (float32 or float64) -> commands ``out (m, width)`` (float64): each
    value clipped to [-1, 1], column 0 times ``max_speed``, column 1 times ``max_turn_rate``, any
    further column as clipped. Returns False, with ``out`` partly written, at the first value that
    is not finite."""
    for i in range(raw.shape[0]):
        for c in range(raw.shape[1]):
            v = float(raw[i, c])
            if not math.isfinite(v):
                return False
            v = min(max(v, -1.0), 1.0)
            if c == 0:
                v *= max_speed
            elif c == 1:
                v *= max_turn_rate
            out[i, c] = v
    return True


def _scaled_block(actions: np.ndarray, shape: tuple, max_speed: float, max_turn_rate: float) -> np.ndarray | None:
    """The commands of raw actions of exactly ``shape`` (float32 or float64, every value finite),
    clipped and scaled in one compiled pass into a new array; None when the block is not that
    common case (another shape or dtype, or a value not finite)."""
    if actions.shape != shape or actions.dtype not in (np.float32, np.float64):
        return None
    out = np.empty(shape)
    width = shape[-1]
    if scaled_commands(actions.reshape(-1, width), float(max_speed), float(max_turn_rate), out.reshape(-1, width)):
        return out
    return None


def _common_dicts(actions: Sequence[Mapping], agents: Sequence[Sequence[str]], width: int) -> np.ndarray | None:
    """Raw ``(K N, width)`` actions (not yet checked for finite values) when every one of the ``K``
    joint actions holds exactly its agents' actions, each a float ndarray of shape ``(width,)``;
    None otherwise."""
    vals: list = []
    for acts, names in zip(actions, agents, strict=True):
        if type(acts) is not dict or len(acts) != len(names):
            return None
        try:
            vals += [acts[a] for a in names]
        except KeyError:
            return None
    if vals and all(type(v) is np.ndarray and v.shape == (width,) and v.dtype.kind == "f" for v in vals):
        return np.array(vals)
    return None


def _common_case(actions, agents: Sequence[str], width: int = 2) -> np.ndarray | None:
    """Raw ``(N, 2)`` actions when the joint action is the common case (a dict holding exactly the
    active agents, each a finite float ndarray of shape (2,)), cheaply; None otherwise."""
    if type(actions) is not dict or len(actions) != len(agents):
        return None
    try:
        vals = [actions[a] for a in agents]
    except KeyError:
        return None
    for v in vals:
        if type(v) is not np.ndarray or v.shape != (width,) or v.dtype.kind != "f":
            return None
    out = np.array(vals, dtype=float)
    return out if np.isfinite(out).all() else None


def _validated(actions, agents: Sequence[str], width: int = 2) -> np.ndarray:
    """Raw ``(N, 2)`` actions after full validation; ActionError naming the agent otherwise."""
    if not isinstance(actions, Mapping):
        raise ActionError(f"actions must be a dict {{agent: array(2)}}, got {type(actions).__name__}")
    extra = [a for a in actions if a not in agents]
    if extra:
        raise ActionError(f"actions for unknown or finished agents {extra}; active agents: {list(agents)}")
    missing = [a for a in agents if a not in actions]
    if missing:
        raise ActionError(f"missing actions for agents {missing}")
    out = np.empty((len(agents), width))
    for i, agent in enumerate(agents):
        try:
            raw = np.asarray(actions[agent])
        except (TypeError, ValueError):  # e.g. ragged nested sequences
            raise ActionError(f"{agent}: action is not numeric: {actions[agent]!r}") from None
        if raw.dtype.kind not in "iuf":  # complex, bool, strings, objects: never silently cast
            raise ActionError(f"{agent}: action is not numeric (real numbers): {actions[agent]!r}")
        a = raw.astype(float)
        if a.shape != (width,):
            what = "(v, omega)" if width == 2 else "(v, omega, scan)"
            raise ActionError(f"{agent}: action must have shape ({width},) = {what} in [-1, 1], got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ActionError(f"{agent}: action contains NaN or inf: {a.tolist()}")
        out[i] = a
    return out
