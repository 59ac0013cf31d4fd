"""parcover_env: multi-robot parallel path coverage as a PettingZoo / Gymnasium environment.

Factories follow PettingZoo's module convention (``parallel_env()``, ``env()``, ``raw_env``);
``make`` is an alias of ``parallel_env``; ``parcover_env.parcover_v0`` / ``parcover_v1`` /
``parcover_v2`` are the factories of each env version under PettingZoo's ``<name>_v<N>`` module
convention (``parcover_v1`` = these; ``parcover_v2``: observations, rewards and a fixed-shape
state to learn from). ``make_vec_env`` (SB3 VecEnv, ``train`` extra)
has one slot per robot per world; ``backend="batched"`` steps many worlds in one process. The
single-robot Gymnasium env is registered as ``parcover_env/SingleRobotCoverage-v0``.
``compare(policy, scenarios, seeds)`` benches a policy of your own beside the expert (the
``parcover bench`` table: IQM with stratified bootstrap CIs).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from parcover_env.errors import ActionError, ConfigError, ParcoverError

if TYPE_CHECKING:  # imported on first use (module ``__getattr__`` below): ``import parcover_env`` stays light
    from parcover_env.config import Scenario
    from parcover_env.envs import ParallelCoverageEnv
    from parcover_env.envs.vec_env import make_vec_env
    from parcover_env.harness.compare import Comparison, compare
    from parcover_env.scenarios import load_scenario, scenario_names

__all__ = [
    "ParallelCoverageEnv", "raw_env", "parallel_env", "env", "make", "Scenario", "load_scenario",
    "scenario_names", "make_vec_env", "compare", "Comparison", "ConfigError", "ActionError", "ParcoverError",
    "__version__",
]
__version__ = "0.3.0"  # the one version string (pyproject reads it; tests/test_version.py)

_LAZY = {
    "ParallelCoverageEnv": ("parcover_env.envs", "ParallelCoverageEnv"),
    "raw_env": ("parcover_env.envs", "ParallelCoverageEnv"),
    "Scenario": ("parcover_env.config", "Scenario"),
    "load_scenario": ("parcover_env.scenarios", "load_scenario"),
    "scenario_names": ("parcover_env.scenarios", "scenario_names"),
    "make_vec_env": ("parcover_env.envs.vec_env", "make_vec_env"),
    "compare": ("parcover_env.harness.compare", "compare"),
    "Comparison": ("parcover_env.harness.compare", "Comparison"),
}


def __getattr__(name: str):
    """The heavy public names (the env class, the config and scenario loaders), imported on first use."""
    if name not in _LAZY:
        raise AttributeError(f"module 'parcover_env' has no attribute {name!r}")
    import importlib

    module, attr = _LAZY[name]
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


def parallel_env(scenario="office", render_mode=None, overrides=None, preset="realistic",
                 max_cycles=None) -> ParallelCoverageEnv:
    """The ParallelEnv for a scenario name, YAML path or ``Scenario``; ``preset="ideal"`` turns
    every error model off; ``max_cycles`` overrides the step limit."""
    from parcover_env.envs import ParallelCoverageEnv

    return ParallelCoverageEnv(scenario, render_mode=render_mode, overrides=overrides, preset=preset,
                               max_cycles=max_cycles)


def env(scenario="office", render_mode=None, overrides=None, preset="realistic", max_cycles=None):
    """The AEC version (``pettingzoo.utils.parallel_to_aec``, each action checked when given:
    :mod:`parcover_env.envs.aec`) of :func:`parallel_env`."""
    from parcover_env.envs.aec import aec_env

    return aec_env(parallel_env(scenario, render_mode=render_mode, overrides=overrides, preset=preset,
                                max_cycles=max_cycles))


make = parallel_env


def _register() -> None:
    """Register the Gymnasium id; and have worker processes started by the ``forkserver`` method
    (SB3 ``SubprocVecEnv``'s default on Linux) import this package first, so that
    ``make_vec_env("parcover_env/SingleRobotCoverage-v0", vec_env_cls=SubprocVecEnv)`` finds the id
    in its workers without a ``parcover_env:`` prefix (Gymnasium 1.x has no entry-point plugins)."""
    import gymnasium

    if "parcover_env/SingleRobotCoverage-v0" not in gymnasium.registry:
        gymnasium.register("parcover_env/SingleRobotCoverage-v0",
                           entry_point="parcover_env.envs.single_agent:SingleRobotCoverageEnv")
    try:
        import multiprocessing.forkserver as forkserver

        # reach-in kept: the stdlib has no public getter of the forkserver's preload list
        preload = list(getattr(forkserver._forkserver, "_preload_modules", ["__main__"]))
        if __name__ not in preload:
            forkserver.set_forkserver_preload([*preload, __name__])
    except (ImportError, AttributeError, ValueError):  # pragma: no cover - platforms without forkserver
        pass


_register()
