"""The Sensor protocol: one ``sense`` signature over a (worlds x robots) axis, rendering apart.

As in VMAS's ``sensors.py``, a sensor is built from its config and measures every robot of every
world in one call from a frozen :class:`SensingState` (what any sensor may read: true poses, walls,
robot radius, who follows whom). World ``k`` draws its random numbers from ``rngs[k]`` only, in
the order a single world would, so world ``k`` of a batch reads bit for bit what a separate env
with the same generator reads. Drawing (plots, frames) is not part of measuring: a sensor that can
draw itself offers ``render`` separately.

The older per-sensor ``measure`` methods keep their signatures (other code calls them); ``sense``
is the one the env's stepper calls, so a new sensor needs no change to the env or the batched
worlds (``parcover_env.envs.obs_spec``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

__all__ = ["SensingState", "Sensor"]


class SensingState(NamedTuple):
    """What a sensor may read at one instant, for ``K`` worlds of ``N`` robots sharing one map (a
    read-only record; made every step, hence a NamedTuple)."""

    poses: np.ndarray
    """True poses ``(K, N, 3)``: x, y (m), theta (rad)."""
    segments: np.ndarray
    """Static wall segments ``(S, 4)`` (m), shared by every world."""
    robot_radius: float
    """Radius of every robot's disc (m): other robots block and echo as discs."""
    predecessor: np.ndarray
    """``(K, N)`` int64: index (within its world) of the robot each robot follows, -1 none."""

    @property
    def n_worlds(self) -> int:
        return self.poses.shape[0]

    @property
    def n_robots(self) -> int:
        return self.poses.shape[1]


@runtime_checkable
class Sensor(Protocol):
    """A sensor every robot carries: ``size`` numbers per robot per reading."""

    @property
    def size(self) -> int:
        """Numbers per robot in one reading."""
        ...

    def sense(self, state: SensingState, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """Readings ``(K, N, size)`` of every robot of every world; world ``k`` draws from ``rngs[k]``."""
        ...
