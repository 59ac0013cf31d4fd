"""Reading scenario YAML and turning mappings into validated ``Scenario`` objects."""

from __future__ import annotations

import copy
import re
from pathlib import Path

import numpy as np
import yaml

from parcover_env.config.presets import apply_preset
from parcover_env.config.schema import Scenario
from parcover_env.config.typed import from_mapping, to_mapping
from parcover_env.errors import ConfigError

__all__ = ["read_yaml", "load_yaml_text", "plain", "deep_merge", "scenario_from_mapping", "scenario_to_yaml",
           "replace_source"]


_FLOAT_12 = re.compile(r"^[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?$")


class _DuplicateKey(yaml.YAMLError):
    def __init__(self, key: str, line: int):
        super().__init__(f"duplicate key {key!r}")
        self.key, self.line = key, line


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """Safe YAML loader that rejects duplicate keys and reads YAML 1.2 floats (``1e9``, ``2.5E-3``)
    as numbers (PyYAML's YAML 1.1 rules read them as strings). Parses with libyaml when PyYAML was
    built with it (the wheels are), else in pure Python."""

    def construct_mapping(self, node, deep=False):
        seen: dict = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                if key in seen:
                    raise _DuplicateKey(str(key), key_node.start_mark.line + 1)
            except TypeError:  # unhashable keys: let PyYAML report them
                break
            seen[key] = True
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))


def load_yaml_text(text: str, source: str = "<string>") -> object:
    """Parse YAML text with the package's rules (duplicate keys rejected, ``1e9`` is a float)."""
    try:
        return yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader subclass
    except _DuplicateKey as exc:
        raise ConfigError(source, exc.key, f"duplicate key (line {exc.line}); each key may appear once") from None


def read_yaml(path: Path) -> object:
    """The parsed contents of a YAML file; errors name the file and line."""
    source = str(path)
    try:
        return load_yaml_text(path.read_text(), source)
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
        if not isinstance(overrides, dict):
            raise ConfigError("overrides", "", f"expected a mapping, got {type(overrides).__name__}")
        overrides = plain(overrides)
        if not isinstance(data, dict):
            raise ConfigError(source, "<top level>", "expected a mapping")
        data = deep_merge(data, overrides)
    try:
        return replace_source(from_mapping(Scenario, data, source), source)
    except ConfigError as exc:
        if overrides and _names(overrides, exc.key):
            raise ConfigError(f"overrides (over {source})", exc.key, exc.message) from None
        raise


def plain(value: object) -> object:
    """``value`` with numpy scalars and arrays turned into Python numbers and lists (recursively)."""
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def _names(overrides: dict, key: str) -> bool:
    """True if the dotted ``key`` (``robot.radius``, ``kpois[2]``) is set by ``overrides``."""
    node: object = overrides
    for part in re.findall(r"[^.\[\]]+", key):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit():
            return True  # inside a list the override replaced as a whole
        else:
            return node is not overrides and not isinstance(node, dict)
    return node is not overrides


def replace_source(scenario: Scenario, source: str) -> Scenario:
    """Same scenario, remembering the file it came from (skips re-validation)."""
    object.__setattr__(scenario, "source", source)
    return scenario


def scenario_to_yaml(scenario: Scenario) -> str:
    return yaml.safe_dump(to_mapping(scenario), sort_keys=False)
