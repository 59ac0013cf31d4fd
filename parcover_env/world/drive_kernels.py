"""Compiled (numba) loop behind :meth:`parcover_env.world.drive.DiffDrive.advance_steps` (public so
that tests and other rooms may use it). The IEEE operations and their order are those of
:meth:`~parcover_env.world.drive.DiffDrive.advance` (no fast-math): the results are the same floats.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def lag_steps(wheels, travel, change, targets, gain, step_max, dt, wheel_base, out):
    """``out.shape[0]`` drive steps in place: per step, ``travel += wheels dt``, the lagged change
    ``(targets - wheels) gain`` clipped to ``+-step_max``, ``change += |change|``; ``out[s]`` the
    body ``(v, omega)`` after step ``s``. ``wheels``, ``travel``, ``change``, ``targets``: ``(n, 2)``."""
    for s in range(out.shape[0]):
        for i in range(wheels.shape[0]):
            for c in range(2):
                w = wheels[i, c]
                travel[i, c] += w * dt
                dv = min(max((targets[i, c] - w) * gain, -step_max), step_max)
                new = w + dv
                change[i, c] += abs(new - w)
                wheels[i, c] = new
            out[s, i, 0] = 0.5 * (wheels[i, 0] + wheels[i, 1])
            out[s, i, 1] = (wheels[i, 1] - wheels[i, 0]) / wheel_base
