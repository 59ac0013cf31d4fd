"""Every ParcoverError subclass pickles round-trip (bench workers raise them across processes)."""

from __future__ import annotations

import contextlib
import importlib
import inspect
import pickle
import pkgutil

import pytest

import parcover_env
from parcover_env.errors import ConfigError, DependencyError, ParcoverError


def _all_error_classes() -> list[type]:
    for mod in pkgutil.walk_packages(parcover_env.__path__, "parcover_env."):
        if mod.name.endswith("__main__"):
            continue
        with contextlib.suppress(ImportError):  # optional dependencies
            importlib.import_module(mod.name)
    seen, todo = [], [ParcoverError]
    while todo:
        cls = todo.pop()
        seen.append(cls)
        todo.extend(cls.__subclasses__())
    return seen


def _instance(cls: type) -> ParcoverError:
    params = [p for p in inspect.signature(cls.__init__).parameters.values()
              if p.name != "self" and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.default is p.empty]
    if not params:
        return cls("something is wrong")
    args = [3 if p.annotation in (int, "int") else f"{p.name}-value" for p in params]
    return cls(*args)


CLASSES = _all_error_classes()


def test_every_known_error_is_found():
    names = {c.__name__ for c in CLASSES}
    assert {"ParcoverError", "ConfigError", "ActionError", "DependencyError", "OutputError",
            "UnreachableKpoiError"} <= names


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
def test_error_pickles_round_trip(cls):
    exc = _instance(cls)
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is cls and str(back) == str(exc) and back.args == exc.args
    assert back.__dict__ == exc.__dict__


def test_config_error_keeps_its_fields_across_processes():
    exc = ConfigError("office.yaml", "robot.radius", "must be > 0")
    back = pickle.loads(pickle.dumps(exc))
    assert (back.source, back.key, back.message) == ("office.yaml", "robot.radius", "must be > 0")
    assert str(back) == "office.yaml: robot.radius: must be > 0"


def test_config_error_survives_a_process_pool():
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(1) as pool, pytest.raises(ConfigError, match="n_robots"):
        pool.submit(parcover_env.parallel_env, "office", None, {"n_robots": -1}).result()


def test_dependency_error_names_the_extra():
    exc = DependencyError("minari", "data", "parcover collect")
    assert str(exc) == "minari is needed for parcover collect: pip install 'parcover_env[data]'"
    assert isinstance(exc, ImportError)
