"""Checks at the env's public entry points (``reset``, ``step``, ``render``, ...): one clear error
naming the argument or the call to make first, raised before anything changes."""

from __future__ import annotations

import numbers
from collections.abc import Mapping

from parcover_env.errors import ArgumentError, CallOrderError

__all__ = ["check_seed", "check_options", "require_episode"]


def check_seed(seed: object, where: str = "reset(seed=...)") -> int | None:
    """``seed`` as ``reset`` takes it: None (a fresh unseeded generator the first time, else the
    running one) or an integer >= 0 (a Python or numpy integer, not a bool); else ArgumentError
    naming ``where`` (the call and argument)."""
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise ArgumentError(f"{where}: expected None or an integer >= 0, got {type(seed).__name__} {_short(seed)}")
    if seed < 0:
        raise ArgumentError(f"{where}: expected None or an integer >= 0, got {int(seed)}")
    return int(seed)


def check_options(options: object) -> None:
    """``reset(options=...)``: None or a mapping, else ArgumentError. This env reads no option yet;
    the keys of a mapping are ignored, as PettingZoo's and Gymnasium's API conventions (and
    ``pettingzoo.test.parallel_api_test``, which passes ``{"options": 1}``) expect."""
    if options is not None and not isinstance(options, Mapping):
        raise ArgumentError(f"reset(options=...): expected None or a dict, got {type(options).__name__} "
                            f"{_short(options)}")


def require_episode(env: object, call: str) -> None:
    """CallOrderError unless ``env`` was reset (``call`` names the method, e.g. ``"step()"``)."""
    if "world" not in vars(env):
        raise CallOrderError(f"{call} before the first reset(): call reset() first")


def _short(value: object, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
