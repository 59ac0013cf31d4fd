"""Reading scenario YAML and turning mappings into validated ``Scenario`` objects."""

from __future__ import annotations

import copy
from pathlib import Path

import yaml

from parcover_env.config.presets import apply_preset
from parcover_env.config.schema import Scenario
from parcover_env.config.typed import from_mapping, to_mapping
from parcover_env.errors import ConfigError

__all__ = ["read_yaml", "deep_merge", "scenario_from_mapping", "scenario_to_yaml", "replace_source"]


def read_yaml(path: Path) -> object:
    """The parsed contents of a YAML file; errors name the file and line."""
    source = str(path)
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        if mark is not None:
            where = f"line {mark.line + 1}"
        else:  # reader errors (bad characters) carry a character position instead
            pos = getattr(exc, "position", 0) or 0
            where = f"line {path.read_text(errors='replace')[:pos].count(chr(10)) + 1}"
        raise ConfigError(source, where, f"invalid YAML: {getattr(exc, 'problem', exc)}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(source, "", f"cannot read file: {exc}") from None


def deep_merge(base: dict, overrides: dict) -> dict:
    """``base`` with ``overrides`` merged in, recursively for nested mappings (inputs untouched)."""
    out = copy.deepcopy(base)
    for k, v in overrides.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = v
    return out


def scenario_from_mapping(data: object, source: str, overrides: dict | None = None,
                          preset: str = "realistic") -> Scenario:
    """A ``Scenario`` from parsed YAML, with ``preset`` applied and ``overrides`` merged on top;
    schema errors name ``source`` and the key."""
    data = apply_preset(data, preset, source)
    if overrides:
        if not isinstance(data, dict):
            raise ConfigError(source, "<top level>", "expected a mapping")
        data = deep_merge(data, overrides)
    return replace_source(from_mapping(Scenario, data, source), source)


def replace_source(scenario: Scenario, source: str) -> Scenario:
    """Same scenario, remembering the file it came from (skips re-validation)."""
    object.__setattr__(scenario, "source", source)
    return scenario


def scenario_to_yaml(scenario: Scenario) -> str:
    return yaml.safe_dump(to_mapping(scenario), sort_keys=False)
