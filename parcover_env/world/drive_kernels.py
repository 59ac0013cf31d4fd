"""Compiled (numba) loops behind :meth:`parcover_env.world.drive.DiffDrive.advance_steps` and
:func:`parcover_env.world.drive.command_steps_all` (public so that tests and other rooms may use
them). The IEEE operations and their order are those of :func:`~parcover_env.world.drive.wheel_targets`
and :meth:`~parcover_env.world.drive.DiffDrive.advance` (no fast-math): the results are the same floats.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def lag_steps(wheels, travel, change, targets, gain, step_max, dt, wheel_base, out):
    """``out.shape[1]`` drive steps in place: per step, ``travel += wheels dt``, the lagged change
    ``(targets - wheels) gain`` clipped to ``+-step_max``, ``change += |change|``; ``out[i, s]`` the
    body ``(v, omega)`` of robot ``i`` after step ``s`` (``out (n, steps, 2)``). ``wheels``,
    ``travel``, ``change``, ``targets``: ``(n, 2)``."""
    for s in range(out.shape[1]):
        for i in range(wheels.shape[0]):
            for c in range(2):
                w = wheels[i, c]
                travel[i, c] += w * dt
                dv = min(max((targets[i, c] - w) * gain, -step_max), step_max)
                new = w + dv
                change[i, c] += abs(new - w)
                wheels[i, c] = new
            out[i, s, 0] = 0.5 * (wheels[i, 0] + wheels[i, 1])
            out[i, s, 1] = (wheels[i, 1] - wheels[i, 0]) / wheel_base


@njit(cache=True)
def wheel_targets_into(commands, wheel_base, wheel_speed_max, out):
    """:func:`parcover_env.world.drive.wheel_targets` of ``commands (n, 2)`` into ``out (n, 2)``: the
    same IEEE operations in the same order (the same floats)."""
    for i in range(commands.shape[0]):
        v = commands[i, 0]
        half = 0.5 * wheel_base * commands[i, 1]
        left = v - half
        right = v + half
        scale = min(1.0, wheel_speed_max / max(max(abs(left), abs(right)), 1e-300))
        out[i, 0] = left * scale
        out[i, 1] = right * scale


@njit(cache=True)
def command_steps(commands, wheel_speed_max, wheels, travel, change, gain, step_max, dt, wheel_base, out):
    """:func:`lag_steps` towards the wheel targets of the unicycle ``commands (n, 2)``
    (:func:`wheel_targets_into`, limited to ``wheel_speed_max``), in one call."""
    targets = np.empty(commands.shape)
    wheel_targets_into(commands, wheel_base, wheel_speed_max, targets)
    lag_steps(wheels, travel, change, targets, gain, step_max, dt, wheel_base, out)
