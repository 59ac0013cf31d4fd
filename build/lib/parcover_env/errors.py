"""Errors raised by parcover_env: one clear line each, never a deep traceback."""

from __future__ import annotations


class ParcoverError(Exception):
    """Base class of every error this package raises on bad input."""


class ConfigError(ParcoverError, ValueError):
    """A scenario file or mapping is malformed; names the source and the key."""

    def __init__(self, source: str, key: str, message: str):
        self.source = source
        self.key = key
        self.message = message
        where = ": ".join(part for part in (source, key) if part)
        super().__init__(f"{where}: {message}")


class ActionError(ParcoverError, ValueError):
    """An action passed to ``step`` is malformed; names the agent and what is wrong."""
