"""``parcover_v0``: version 0's dynamics and observations, kept for comparisons with old results.

v0 had instant velocity, zero-mean per-step odometry noise, an ideal ray sonar, a perfectly mounted
Kinect and no pose-covariance observation entries: exactly the ``ideal`` preset of v1, which these
factories apply by default. Infos follow v1's flat convention. New work should use
:mod:`parcover_env.parcover_v1`.
"""

from __future__ import annotations

from parcover_env import ParallelCoverageEnv
from parcover_env.envs.aec import aec_env

__all__ = ["env", "parallel_env", "raw_env"]


class raw_env(ParallelCoverageEnv):  # noqa: N801 - PettingZoo's factory name
    """v0's ParallelEnv class: ParallelCoverageEnv with the ``ideal`` preset by default, named
    ``parcover_v0`` in ``metadata["name"]``."""

    metadata = {**ParallelCoverageEnv.metadata, "name": "parcover_v0"}

    def __init__(self, scenario="office", render_mode=None, overrides=None, preset="ideal", max_cycles=None):
        super().__init__(scenario, render_mode=render_mode, overrides=overrides, preset=preset, max_cycles=max_cycles)


def parallel_env(scenario="office", render_mode=None, overrides=None, preset="ideal", max_cycles=None) -> raw_env:
    """v0's ParallelEnv: :func:`parcover_env.parallel_env` with the ``ideal`` preset."""
    return raw_env(scenario, render_mode=render_mode, overrides=overrides, preset=preset, max_cycles=max_cycles)


def env(scenario="office", render_mode=None, overrides=None, preset="ideal", max_cycles=None):
    """v0's AEC env: :func:`parcover_env.env` with the ``ideal`` preset."""
    return aec_env(parallel_env(scenario, render_mode=render_mode, overrides=overrides, preset=preset,
                                max_cycles=max_cycles))
