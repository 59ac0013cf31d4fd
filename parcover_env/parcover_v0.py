"""``parcover_v0``: version 0's dynamics and observations, kept for comparisons with old results.

v0 had instant velocity, zero-mean per-step odometry noise, an ideal ray sonar, a perfectly mounted
Kinect and no pose-covariance observation entries: exactly the ``ideal`` preset of v1, which these
factories apply by default. Infos follow v1's flat convention. New work should use
:mod:`parcover_env.parcover_v1`.
"""

from __future__ import annotations

from functools import partial

import parcover_env
from parcover_env import ParallelCoverageEnv

__all__ = ["env", "parallel_env", "raw_env"]

raw_env = partial(ParallelCoverageEnv, preset="ideal")


def parallel_env(scenario="office", render_mode=None, overrides=None, preset="ideal"):
    """v0's ParallelEnv: :func:`parcover_env.parallel_env` with the ``ideal`` preset."""
    return parcover_env.parallel_env(scenario, render_mode=render_mode, overrides=overrides, preset=preset)


def env(scenario="office", render_mode=None, overrides=None, preset="ideal"):
    """v0's AEC env: :func:`parcover_env.env` with the ``ideal`` preset."""
    return parcover_env.env(scenario, render_mode=render_mode, overrides=overrides, preset=preset)
