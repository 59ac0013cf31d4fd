"""Scenarios by name: the shipped YAMLs, ``generated:SEED`` maps, or a path; loaded and checked."""

from __future__ import annotations

import difflib
from importlib import resources
from pathlib import Path

from parcover_env.config import Scenario, read_yaml, scenario_from_mapping, to_mapping
from parcover_env.errors import ConfigError
from parcover_env.scenarios.validation import validate_geometry
from parcover_env.world.map_model import map_model

__all__ = ["configs_dir", "scenario_names", "resolve_scenario_path", "load_scenario"]


def configs_dir() -> Path:
    """Folder of the shipped scenario YAMLs: ``configs/`` of a source checkout, else the installed
    ``parcover_env/configs``."""
    checkout = Path(__file__).resolve().parents[2] / "configs"
    if (checkout / "__init__.py").is_file():
        return checkout
    return Path(str(resources.files("parcover_env.configs")))


def scenario_names() -> list[str]:
    """Names of the scenarios shipped with the package."""
    return sorted(p.stem for p in configs_dir().glob("*.yaml"))


def resolve_scenario_path(name_or_path: str | Path) -> Path:
    """A shipped scenario name (``office``) or a path to a YAML file."""
    text = str(name_or_path)
    if text.endswith((".yaml", ".yml")) or "/" in text or "\\" in text:
        path = Path(text)
        if not path.is_file():
            raise ConfigError(text, "", "scenario file not found")
        return path
    path = configs_dir() / f"{text}.yaml"
    if not path.is_file():
        close = difflib.get_close_matches(text, scenario_names(), n=1)
        hint = f"did you mean '{close[0]}'?" if close else f"shipped: {', '.join(scenario_names())}"
        raise ConfigError(text, "", f"unknown scenario name; {hint}")
    return path


def load_scenario(name_or_path: str | Path | Scenario, overrides: dict | None = None,
                  preset: str = "realistic") -> Scenario:
    """Load a scenario by shipped name, ``generated:SEED``, YAML path, or pass a ``Scenario`` through.

    ``preset`` (``realistic`` or ``ideal``, see :mod:`parcover_env.config.presets`) is applied to
    the file's contents, then ``overrides``, a (nested) mapping such as
    ``{"n_robots": 3, "episode": {"max_steps": 500}}``, is merged on top before validation.
    Errors are one ``ConfigError`` naming the source and the dotted key.
    """
    if isinstance(name_or_path, Scenario):
        if not overrides and preset == "realistic":
            return name_or_path
        data, source = to_mapping(name_or_path), name_or_path.source
    elif isinstance(name_or_path, str) and name_or_path.startswith("generated:"):
        from parcover_env.scenarios.generator import generate_scenario_mapping

        source = name_or_path
        data = generate_scenario_mapping(name_or_path.split(":", 1)[1], source)
    else:
        path = resolve_scenario_path(name_or_path)
        source = str(path)
        data = read_yaml(path)
    scenario = scenario_from_mapping(data, source, overrides, preset)
    try:
        validate_geometry(scenario, map_model(scenario.map, True), map_model(scenario.map, False))
    except ConfigError as exc:
        raise ConfigError(source, exc.key, exc.message) from None
    return scenario
