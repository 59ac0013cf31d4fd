"""The ``parcover`` command line (thin: parse, call one function, print)."""

from parcover_env.cli.main import main

__all__ = ["main"]
