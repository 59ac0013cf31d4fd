"""Stepper part 1a over ``K`` worlds (:func:`act`): actions -> commands, drive and physics, pose estimates.

The worlds of one scenario act together; the single env is ``K = 1`` of the same code. The joint
actions of all worlds become one ``(K, N, A)`` array of commands (:func:`to_commands_all`), the
drives of all worlds turn them into body velocities in one compiled call
(:func:`~parcover_env.world.drive.command_steps_rows`), each world's pymunk space integrates its
physics (one space per world; :func:`~parcover_env.world.physics.step_all` points the compiled
velocity callbacks of all worlds' bodies at their rows in one call and steps all spaces in one
compiled loop), and the pose estimators of all worlds update together
(:func:`~parcover_env.localization.estimator.update_all`: the wheel odometry of all ``K N`` robots
in one compiled call, the Kinect systems in one batch). World ``k`` draws from its own generator in
the order it would alone, so every world is bit for bit a separate env.

The joint action is validated here too: one clear ActionError, and never a state change, on bad
input; the common case (finite values of the right shape) is checked, clipped and scaled in one
compiled pass (:func:`scaled_commands`, the same float operations as the numpy formulas: ``np.clip``
to [-1, 1], then ``v * max_speed`` and ``omega * max_turn_rate``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from parcover_env.config import PhysicsConfig
from parcover_env.errors import ActionError
from parcover_env.localization.estimator import ActRows, FixRequest, act_rows, update_all
from parcover_env.sim.contract import StepWorld
from parcover_env.world.batching import stack
from parcover_env.world.drive import command_steps_rows
from parcover_env.world.physics import poses_all, step_all

__all__ = ["Acted", "act", "to_commands", "to_commands_all"]


class Acted(NamedTuple):
    """What the act phase hands to the score phase."""

    before: np.ndarray
    """The true poses ``(K, N, 3)`` before the step."""
    true: np.ndarray
    """The true poses ``(K, N, 3)`` after the step."""
    rows: ActRows
    """The shared rows of the worlds' pose estimators (estimates, covariances, ...), every world's
    attached (to read only, this step)."""


def act(worlds: Sequence[StepWorld], actions: Sequence[dict[str, Any]] | np.ndarray) -> Acted:
    """Act, integrate the physics and update the pose estimator of every world (``actions[k]``: world
    ``k``'s joint action dict, or ``actions`` one array ``(K, N, A)``: row ``[k, i]`` the action of
    world ``k``'s ``i``-th agent); returns the true poses ``(K, N, 3)`` before and after the step and
    the estimators' rows.
    Bad actions raise :class:`~parcover_env.errors.ActionError` before any world changes."""
    for w in worlds:
        if not w.agents:
            raise RuntimeError("step() called on a finished episode; call reset() first")
    first = worlds[0]
    s = first.scenario
    scanning = first.scanner is not None
    raw = to_commands_all(actions, [w.agents for w in worlds], s.robot.max_speed, s.robot.max_turn_rate,
                          width=3 if scanning else 2)
    commands = np.ascontiguousarray(raw[..., :2]) if scanning else raw
    for w, c in zip(worlds, commands, strict=True):
        w.commands = c
        w.steps += 1
    if scanning:
        for w, r in zip(worlds, raw, strict=True):
            w.scanner.request(r[:, 2], w.commands)  # scanning robots are held still
    physics = [w.world for w in worlds]
    estimators, drives = [w.estimator for w in worlds], [p.drive for p in physics]
    rows = act_rows(estimators, drives)  # the drives' and estimators' arrays as rows of shared blocks
    before = poses_all(physics)
    step_all(physics, commands, _drive(rows, s.physics, commands))
    true = poses_all(physics)
    fixes = update_all(estimators, true, commands, drives, [p.time for p in physics],
                       stack([w.team.leader for w in worlds]), [w.np_random for w in worlds], rows)
    for w, f in zip(worlds, fixes, strict=True):
        kinect = f.get("kinect")
        if kinect:  # a Kinect fix is a message to a leader
            w.team.count_pose_fixes(len(kinect))
    if scanning and s.observation.pose_source == "ground_truth":  # no sources ran: scans end
        for w, t in zip(worlds, true, strict=True):
            w.scanner.fixes(FixRequest(w.world.time, t, w.estimate.copy(), w.team.leader, w.estimator.covariance),
                            w.np_random)
    return Acted(before, true, rows)


def _drive(rows: ActRows, physics: PhysicsConfig, commands: np.ndarray) -> np.ndarray | None:
    """Body velocities ``(K, N, substeps, 2)`` of every world's drive for ``commands (K, N, 2)``
    (advancing the drives in their shared rows), or None when the worlds have no drive
    (``drive: instant``)."""
    if rows.drives is None:
        return None
    b = rows.drives.blocks
    return command_steps_rows(rows.drives.owners[0].cfg, b["wheels"], b["travel"], b["speed_change"], commands,
                              physics.dt, physics.substeps)


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
