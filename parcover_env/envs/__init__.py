"""The environments: the PettingZoo parallel env, its single-robot Gymnasium view, the SB3 VecEnv.

``ParallelCoverageEnv`` is imported on first use (module ``__getattr__``), so that importing one
module of this package (the simulator core reads the pose estimator and the observation spec from
here) does not import the env, which imports the core."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from parcover_env.envs.parallel import ParallelCoverageEnv

__all__ = ["ParallelCoverageEnv"]


def __getattr__(name: str) -> Any:
    if name == "ParallelCoverageEnv":
        from parcover_env.envs.parallel import ParallelCoverageEnv

        return ParallelCoverageEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
