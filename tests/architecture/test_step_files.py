"""A ratchet on the engine's spread (issue 41): the package files whose Python code runs in one
``env.step`` of ``tree``, counted by ``benchmarks/step_files.py``'s profiler hook, may only shrink.
Lower :data:`MAX_FILES` when a change brings the count down; never raise it to let a change pass."""

from __future__ import annotations

import importlib.util
from pathlib import Path

MAX_FILES = 32
"""The count after issue 41's second session (38 before the first, 36 after it;
``PYTHONPATH=. python benchmarks/step_files.py``); the issue's goal is 15."""

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "step_files.py"


def _step_files():
    spec = importlib.util.spec_from_file_location("step_files", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_files_one_step_of_tree_runs_do_not_grow():
    per_step = _step_files().count_step_files("tree", steps=3, warmup=2)
    files = set().union(*per_step)
    assert all(f.startswith("parcover_env/") and f.endswith(".py") for f in files), files
    assert "parcover_env/envs/parallel.py" in files  # the hook sees the step itself
    assert len(files) <= MAX_FILES, f"{len(files)} files run in one step (ratchet {MAX_FILES}): {sorted(files)}"


def test_the_counter_keeps_package_files_only():
    module = _step_files()
    assert module._package_file("<string>") is None and module._package_file("<frozen importlib._bootstrap>") is None
    assert module._package_file(str(module.PACKAGE / "envs" / "parallel.py")) == "parcover_env/envs/parallel.py"
    assert module._package_file("/usr/lib/python3/json/__init__.py") is None


def test_only_files_of_the_package_count():
    """A virtualenv inside the checkout (CI's ``.venv``) sits beside the package: its files do not count."""
    module = _step_files()
    root = module.PACKAGE.parent
    assert module._package_file(str(module.PACKAGE / "envs" / "parallel.py")) == "parcover_env/envs/parallel.py"
    assert module._package_file(str(root / ".venv" / "lib" / "numpy" / "_methods.py")) is None
    assert module._package_file(str(root / "benchmarks" / "step_files.py")) is None
    assert module._package_file("<frozen importlib._bootstrap>") is None
    assert module._package_file(str(module.PACKAGE / "configs" / "office.yaml")) is None
