"""Errors raised by parcover_env: one clear line each, never a deep traceback.

Every error pickles round-trip (same class, message and attributes), so an error raised in a
benchmark worker process reaches the parent as itself, not as ``BrokenProcessPool``.
"""

from __future__ import annotations

__all__ = ["ParcoverError", "ConfigError", "ActionError", "ArgumentError", "CallOrderError", "CheckpointError",
           "DependencyError", "OutputError"]


def _rebuild(cls: type, args: tuple, state: dict) -> ParcoverError:
    """Unpickle an error without calling its ``__init__`` (whose signature varies by subclass)."""
    exc = cls.__new__(cls)
    exc.args = args
    exc.__dict__.update(state)
    return exc


class ParcoverError(Exception):
    """Base class of every error this package raises on bad input."""

    def __reduce__(self):
        return _rebuild, (type(self), self.args, dict(self.__dict__))


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


class ArgumentError(ParcoverError, ValueError):
    """An argument of a public call is malformed (e.g. ``reset(seed=...)``); names the argument and
    the accepted values."""


class CallOrderError(ParcoverError, RuntimeError):
    """A call made in the wrong order (``step`` before ``reset``, after the episode ended, ...); says
    what to call first. The env is unchanged."""


class CheckpointError(ParcoverError, ValueError):
    """A policy checkpoint cannot be used (corrupt, empty, another format or another policy's);
    names the file and what is wrong."""

    def __init__(self, path: str, what: str, problem: str):
        self.path = str(path)
        self.what = what
        self.problem = problem
        super().__init__(f"cannot load {what} {path}: {problem}")


class DependencyError(ParcoverError, ImportError):
    """An optional dependency is missing; names the package and the extra that installs it."""

    def __init__(self, package: str, extra: str, purpose: str = ""):
        self.package = package
        self.extra = extra
        for_what = f" for {purpose}" if purpose else ""
        super().__init__(f"{package} is needed{for_what}: pip install 'parcover_env[{extra}]'")


class OutputError(ParcoverError, OSError):
    """An output file or directory cannot be written; names the path."""


def require(module: str, extra: str, purpose: str = "", package: str | None = None):
    """Import optional ``module`` or raise :class:`DependencyError` naming the extra to install."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise DependencyError(package or module.split(".")[0], extra, purpose) from None
