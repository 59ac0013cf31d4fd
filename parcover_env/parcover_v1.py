"""``parcover_v1``: the environment under PettingZoo's ``<name>_v<N>`` module convention.

``from parcover_env import parcover_v1; env = parcover_v1.parallel_env("office")`` (like
``from pettingzoo.mpe import simple_spread_v3``). The version number changes when the environment's
observations, rewards or dynamics change incompatibly (see the env docstring's version history).
"""

from parcover_env import ParallelCoverageEnv, env, parallel_env

__all__ = ["env", "parallel_env", "raw_env"]

raw_env = ParallelCoverageEnv
