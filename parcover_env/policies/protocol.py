"""The ``Policy`` protocol: what the harness, the CLI and the dataset writer call on anything that drives.

A policy maps the env's observations to actions, ``{agent: obs} -> {agent: (v, w)}`` with both
components in [-1, 1] (fractions of the robot's speed and turn-rate limits). Subclass
:class:`Policy` to inherit the documented defaults of ``reset``, ``stats`` and ``belief``; a class
that defines all four methods itself satisfies the protocol structurally (``isinstance`` works,
the protocol is runtime-checkable).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Policy", "Observations", "Actions"]

Observations = dict[str, np.ndarray]
"""One observation vector per live agent, as ``env.reset``/``env.step`` return them."""
Actions = dict[str, np.ndarray]
"""One ``(2,)`` float32 action per agent: ``(v, w)`` as fractions of the robot's limits, in [-1, 1]."""


@runtime_checkable
class Policy(Protocol):
    """Drives a team: ``reset`` at the start of each episode, then ``act`` once per step."""

    def act(self, observations: Observations) -> Actions:
        """The actions of every agent in ``observations``."""
        ...

    def reset(self, observations: Observations | None = None) -> None:
        """Forget the last episode; called with the first observations after ``env.reset``.

        Default: nothing to forget (a memoryless policy)."""
        return None

    def stats(self) -> dict:
        """Counters merged into the episode summary (e.g. how many sonar fixes were taken).

        Default: none (an empty dict)."""
        return {}

    def belief(self) -> np.ndarray | None:
        """``(N, 3)`` poses ``(x, y, theta)`` the robots steer by, if the policy keeps its own
        estimate (m, rad); the failure classifier compares them with the truth.

        Default: None (the policy steers by the env's observed estimate)."""
        return None
