"""The two field checks every config dataclass uses: one clear ``ConfigError`` naming the key."""

from __future__ import annotations

from typing import Any

from parcover_env.errors import ConfigError

__all__ = ["check", "positive"]


def check(ok: bool, key: str, message: str) -> None:
    """Raise ``ConfigError`` for ``key`` with ``message`` unless ``ok``."""
    if not ok:
        raise ConfigError("", key, message)


def positive(obj: Any, *names: str) -> None:
    """Every field in ``names`` of ``obj`` must be > 0."""
    for name in names:
        check(getattr(obj, name) > 0, name, f"must be > 0, got {getattr(obj, name)}")
