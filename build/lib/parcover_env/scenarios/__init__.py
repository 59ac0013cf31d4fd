"""Scenarios: the registry of names, the map generator, and the Mission built once per scenario."""

from parcover_env.scenarios.mission import Mission, mission_for
from parcover_env.scenarios.progress import RouteTracker
from parcover_env.scenarios.registry import configs_dir, load_scenario, resolve_scenario_path, scenario_names

__all__ = [
    "Mission", "mission_for", "RouteTracker", "configs_dir", "load_scenario", "resolve_scenario_path", "scenario_names",
]
