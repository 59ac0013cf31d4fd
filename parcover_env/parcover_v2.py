"""``parcover_v2``: the environment with observations, rewards and a global state to learn from.

``from parcover_env import parcover_v2; env = parcover_v2.parallel_env("office")``. The same env
class as :mod:`parcover_env.parcover_v1` with :data:`V2_SETTINGS` merged under the caller's
``overrides`` (over the scenario's own values): ``observation.version: 2`` (the ``v2`` observation
entries, ``info[agent]["route_done"]``, the fixed-shape token ``state()``) and the v2 reward weights
(``own_kpoi`` 10 per KPOI of its own route a robot visits, ``kpoi`` 1 as a team bonus). See the env
docstring's observation table, state table and version history.
"""

from __future__ import annotations

from parcover_env import ParallelCoverageEnv
from parcover_env.config import deep_merge
from parcover_env.envs.aec import aec_env

__all__ = ["V2_SETTINGS", "env", "parallel_env", "raw_env"]

V2_SETTINGS = {"observation": {"version": 2}, "rewards": {"own_kpoi": 10.0, "kpoi": 1.0}}
"""What v2 sets over a scenario (the caller's ``overrides`` win)."""


class raw_env(ParallelCoverageEnv):  # noqa: N801 - PettingZoo's factory name
    """v2's ParallelEnv class: ParallelCoverageEnv with :data:`V2_SETTINGS`, named ``parcover_v2``."""

    metadata = {**ParallelCoverageEnv.metadata, "name": "parcover_v2"}

    def __init__(self, scenario="office", render_mode=None, overrides=None, preset="realistic", max_cycles=None):
        super().__init__(scenario, render_mode=render_mode, overrides=deep_merge(V2_SETTINGS, overrides or {}),
                         preset=preset, max_cycles=max_cycles)


def parallel_env(scenario="office", render_mode=None, overrides=None, preset="realistic", max_cycles=None) -> raw_env:
    """v2's ParallelEnv (see the module docstring)."""
    return raw_env(scenario, render_mode=render_mode, overrides=overrides, preset=preset, max_cycles=max_cycles)


def env(scenario="office", render_mode=None, overrides=None, preset="realistic", max_cycles=None):
    """v2's AEC env."""
    return aec_env(parallel_env(scenario, render_mode=render_mode, overrides=overrides, preset=preset,
                                max_cycles=max_cycles))
