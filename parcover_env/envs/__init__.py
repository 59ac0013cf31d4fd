"""The environments: the PettingZoo parallel env, its single-robot Gymnasium view, the SB3 VecEnv."""

from parcover_env.envs.parallel import ParallelCoverageEnv

__all__ = ["ParallelCoverageEnv"]
