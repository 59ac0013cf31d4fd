"""Shared fixtures."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BASELINES = Path(__file__).resolve().parents[1] / "baselines"


@pytest.fixture(scope="session")
def load_baseline():
    """``load_baseline(name)``: the single-file trainer ``baselines/<name>.py`` as a module."""

    def load(name: str):
        spec = importlib.util.spec_from_file_location(f"baseline_{name}", BASELINES / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod
        spec.loader.exec_module(mod)
        return mod

    return load
