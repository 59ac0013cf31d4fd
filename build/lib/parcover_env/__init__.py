"""parcover_env: multi-robot parallel path coverage as a PettingZoo / Gymnasium environment.

Factories follow PettingZoo's module convention (``parallel_env()``, ``env()``, ``raw_env``);
``make`` is an alias of ``parallel_env``. The single-robot Gymnasium env is registered as
``parcover_env/SingleRobotCoverage-v0``.
"""

from __future__ import annotations

from parcover_env.config import Scenario
from parcover_env.env import ParallelCoverageEnv
from parcover_env.errors import ActionError, ConfigError, ParcoverError
from parcover_env.scenarios import load_scenario, scenario_names

__all__ = [
    "ParallelCoverageEnv", "raw_env", "parallel_env", "env", "make", "Scenario", "load_scenario",
    "scenario_names", "ConfigError", "ActionError", "ParcoverError", "__version__",
]
__version__ = "0.1.0"

raw_env = ParallelCoverageEnv


def parallel_env(scenario="office", render_mode=None, overrides=None, preset="realistic") -> ParallelCoverageEnv:
    """The ParallelEnv for a scenario name, YAML path or ``Scenario``; ``preset="ideal"`` turns
    every error model off."""
    return ParallelCoverageEnv(scenario, render_mode=render_mode, overrides=overrides, preset=preset)


def env(scenario="office", render_mode=None, overrides=None, preset="realistic"):
    """The AEC version (``pettingzoo.utils.parallel_to_aec``) of :func:`parallel_env`."""
    from pettingzoo.utils.conversions import parallel_to_aec

    return parallel_to_aec(parallel_env(scenario, render_mode=render_mode, overrides=overrides, preset=preset))


make = parallel_env


def _register() -> None:
    import gymnasium

    if "parcover_env/SingleRobotCoverage-v0" not in gymnasium.registry:
        gymnasium.register("parcover_env/SingleRobotCoverage-v0",
                           entry_point="parcover_env.env.single_agent:SingleRobotCoverageEnv")


_register()
