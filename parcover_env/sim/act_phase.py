"""Stepper part 1a over ``K`` worlds (:func:`act`): actions -> commands, drive and physics, pose estimates.

The worlds of one scenario act together; the single env is ``K = 1`` of the same code. The joint
actions of all worlds become one ``(K, N, A)`` array of commands
(:func:`~parcover_env.sim.actions.to_commands_all`), the drives of all worlds turn them into body
velocities in one compiled call (:func:`~parcover_env.world.drive.command_steps_rows`), each world's
pymunk space integrates its physics (one space per world; :func:`~parcover_env.world.physics.step_all`
points the compiled velocity callbacks of all worlds' bodies at their rows in one call and steps
all spaces in one compiled loop), and the
pose estimators of all worlds update together (:func:`~parcover_env.localization.estimator.update_all`: the
wheel odometry of all ``K N`` robots in one compiled call, the Kinect systems in one batch). World
``k`` draws from its own generator in the order it would alone, so every world is bit for bit a
separate env.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from parcover_env.config import PhysicsConfig
from parcover_env.localization.estimator import ActRows, FixRequest, act_rows, update_all
from parcover_env.sim.actions import to_commands_all
from parcover_env.sim.contract import StepWorld
from parcover_env.world.batching import stack
from parcover_env.world.drive import command_steps_rows
from parcover_env.world.physics import poses_all, step_all

__all__ = ["Acted", "act"]


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
