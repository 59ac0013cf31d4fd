"""Generic mapping -> frozen dataclass conversion with precise, did-you-mean errors.

Every dataclass field is converted from its type hint; unknown keys are rejected with the
closest known key as a suggestion, and each error names the source file and the dotted key.
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
import math
import types
from typing import Any, Literal, Union, get_args, get_origin, get_type_hints

from parcover_env.errors import ConfigError

__all__ = ["from_mapping", "to_mapping"]


def _describe(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _join(key: str, sub: str | int) -> str:
    if isinstance(sub, int):
        return f"{key}[{sub}]"
    return f"{key}.{sub}" if key else sub


def from_mapping(cls: type, data: Any, source: str, key: str = "") -> Any:
    """Build dataclass ``cls`` from ``data`` (a mapping); raise ConfigError(source, key, ...)."""
    return _convert(cls, data, source, key)


def _convert(tp: Any, value: Any, source: str, key: str) -> Any:
    origin = get_origin(tp)
    if dataclasses.is_dataclass(tp):
        return _convert_dataclass(tp, value, source, key)
    if tp is Any:
        return value
    if origin is Literal:
        options = get_args(tp)
        if value not in options or isinstance(value, bool) != any(isinstance(o, bool) for o in options):
            raise ConfigError(source, key, f"expected one of {list(options)}, got {_describe(value)}")
        return value
    if origin in (Union, types.UnionType):
        args = get_args(tp)
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, source, key)
            except ConfigError as exc:
                errors.append(exc.message)
        raise ConfigError(source, key, " or ".join(dict.fromkeys(errors)))
    if origin is tuple:
        return _convert_tuple(tp, value, source, key)
    if origin is dict:  # a section owned by a higher room (e.g. ``expert``): a mapping, validated there
        if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
            raise ConfigError(source, key, f"expected a mapping with text keys, got {_describe(value)}")
        return copy.deepcopy(value)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(source, key, f"expected true/false, got {_describe(value)}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(source, key, f"expected an integer, got {_describe(value)}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(source, key, f"expected a number, got {_describe(value)}")
        if not math.isfinite(value):
            raise ConfigError(source, key, f"expected a finite number, got {value}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(source, key, f"expected a string, got {_describe(value)}")
        return value
    raise TypeError(f"unsupported config type {tp!r} at {key}")  # programming error


def _convert_tuple(tp: Any, value: Any, source: str, key: str) -> tuple:
    args = get_args(tp)
    if not isinstance(value, (list, tuple)):
        raise ConfigError(source, key, f"expected a list, got {_describe(value)}")
    if len(args) == 2 and args[1] is Ellipsis:
        return tuple(_convert(args[0], v, source, _join(key, i)) for i, v in enumerate(value))
    if len(value) != len(args):
        raise ConfigError(source, key, f"expected a list of {len(args)} items, got {len(value)}")
    return tuple(_convert(a, v, source, _join(key, i)) for i, (a, v) in enumerate(zip(args, value)))


def _convert_dataclass(cls: type, value: Any, source: str, key: str) -> Any:
    if not isinstance(value, dict):
        raise ConfigError(source, key or "<top level>", f"expected a mapping, got {_describe(value)}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init and not f.metadata.get("internal")}
    hints = get_type_hints(cls)
    for name in value:
        if not isinstance(name, str) or name not in fields:
            close = difflib.get_close_matches(str(name), list(fields), n=1, cutoff=0.6)
            hint = f"; did you mean '{close[0]}'?" if close else f"; known keys: {', '.join(fields)}"
            raise ConfigError(source, _join(key, str(name)), f"unknown key{hint}")
    kwargs = {}
    for name, field in fields.items():
        if name in value:
            kwargs[name] = _convert(hints[name], value[name], source, _join(key, name))
        elif field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING:
            raise ConfigError(source, _join(key, name), "required key is missing")
    try:
        return cls(**kwargs)
    except ConfigError as exc:  # __post_init__ checks report keys relative to this object
        raise ConfigError(source, _join(key, exc.key) if exc.key else key, exc.message) from None


def to_mapping(obj: Any) -> Any:
    """Inverse of ``from_mapping``: a plain dict/list structure (YAML-serializable)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_mapping(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if f.init and not f.metadata.get("internal")}
    if isinstance(obj, tuple):
        return [to_mapping(v) for v in obj]
    return obj

