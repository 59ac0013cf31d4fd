"""Compiled (numba) loop behind :func:`parcover_env.sim.actions.to_commands_all` (import only through
it): the common case's finiteness check, clip and scaling in one pass, the same float operations as
the numpy formulas (``np.clip`` to [-1, 1], then ``v * max_speed`` and ``omega * max_turn_rate``)."""

from __future__ import annotations

import math

from numba import njit


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
