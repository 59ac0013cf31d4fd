"""Policies written outside the package: the ``py:MODULE:ATTR`` spec, and factories, classes or
objects handed to :func:`parcover_env.compare`.

``ATTR`` (or the object given to ``compare``) is one of

* a factory ``(env, seed) -> Policy`` or ``(env) -> Policy`` (``seed``: the episode's seed, for a
  stochastic policy's generator), or a Policy class whose constructor takes ``(env, seed)``,
  ``(env)`` or nothing;
* a Policy object (used as it is; ``reset`` is called at the start of every episode).

A Policy is anything with ``act``, ``reset``, ``stats`` and ``belief`` (subclass
:class:`~parcover_env.policies.Policy` for the last three). A policy with an ``obs_shape`` attribute
is checked against the env's observation shape by the registry (one error naming both shapes). A
factory or class with an ``env_overrides`` mapping attribute (e.g. ``{"observation": {"version":
2}}``) has its episodes run on the scenario with those overrides. Every problem is one
:class:`~parcover_env.errors.ParcoverError` naming the spec.
"""

from __future__ import annotations

import importlib
import inspect
from typing import Any

from parcover_env.errors import ParcoverError
from parcover_env.policies.protocol import Policy

__all__ = ["PY_PREFIX", "load_attribute", "check_python_spec", "policy_from", "env_overrides_of", "POLICY_METHODS"]

PY_PREFIX = "py"
"""The registry name of these specs: ``py:MODULE:ATTR``."""
POLICY_METHODS = ("act", "reset", "stats", "belief")
"""What a Policy object must have (the :class:`~parcover_env.policies.Policy` protocol)."""


def _split(target: str, spec: str) -> tuple[str, str]:
    module, sep, attr = target.partition(":")
    if not sep or not module or not attr:
        raise ParcoverError(f"policy '{spec}': give MODULE:ATTR after 'py:', e.g. py:my_pkg.agents:make_policy")
    if not all(part.isidentifier() for part in module.split(".")):
        raise ParcoverError(f"policy '{spec}': '{module}' is not a module path (dotted Python names)")
    if not all(part.isidentifier() for part in attr.split(".")):
        raise ParcoverError(f"policy '{spec}': '{attr}' is not an attribute name")
    return module, attr


def load_attribute(target: str, spec: str | None = None) -> Any:
    """The object ``ATTR`` of ``MODULE`` named by ``target`` = ``"MODULE:ATTR"`` (``ATTR`` may be
    dotted: ``Agents.make``). ``spec`` names the spec in the errors (default ``py:<target>``)."""
    spec = spec or f"{PY_PREFIX}:{target}"
    module_name, attr = _split(target, spec)
    try:
        obj: Any = importlib.import_module(module_name)
    except Exception as exc:  # not found, or the module itself failed: one line naming the module
        raise ParcoverError(f"policy '{spec}': cannot import module '{module_name}' ({type(exc).__name__}: "
                            f"{exc}); is the folder that holds it on PYTHONPATH?") from exc
    for i, part in enumerate(attr.split(".")):
        if not hasattr(obj, part):
            where = module_name + "".join("." + p for p in attr.split(".")[:i])
            raise ParcoverError(f"policy '{spec}': '{where}' has no attribute '{part}'")
        obj = getattr(obj, part)
    return obj


def check_python_spec(target: str, spec: str | None = None) -> None:
    """Raise ParcoverError unless ``MODULE:ATTR`` imports and is a Policy object, a Policy class or a
    callable (a factory); what a factory returns is checked when it is called (:func:`policy_from`)."""
    spec = spec or f"{PY_PREFIX}:{target}"
    obj = load_attribute(target, spec)
    if not (_is_policy(obj) or callable(obj)):
        raise ParcoverError(f"policy '{spec}': {type(obj).__name__} is not callable: give a factory "
                            "(env, seed) -> Policy, a Policy class or a Policy object")
    env_overrides_of(obj, spec)


def _is_policy(obj: Any) -> bool:
    return not isinstance(obj, type) and isinstance(obj, Policy)


def _missing(obj: Any) -> list[str]:
    return [m for m in POLICY_METHODS if not callable(getattr(obj, m, None))]


def _name(obj: Any) -> str:
    return getattr(obj, "__qualname__", None) or type(obj).__name__


def policy_from(obj: Any, env, seed: int | None, label: str) -> Policy:
    """The Policy that ``obj`` gives for ``env``: ``obj`` itself if it is a Policy object, else
    ``obj(env, seed)``, ``obj(env)`` or ``obj()`` (the first its signature accepts). ParcoverError,
    naming ``label``, when it is neither, or when the call raises or returns something else."""
    if _is_policy(obj):
        return obj
    if not callable(obj):
        raise ParcoverError(f"policy '{label}': {type(obj).__name__} is neither a Policy (with "
                            f"{', '.join(POLICY_METHODS)}) nor a factory (env, seed) -> Policy")
    args = _arguments(obj, env, seed, label)
    call = f"{_name(obj)}({_shown(args)})"
    try:
        policy = obj(*args)
    except ParcoverError:
        raise
    except Exception as exc:  # the user's code failed: one line naming the call (the cause stays chained)
        raise ParcoverError(f"policy '{label}': {call} raised {type(exc).__name__}: {exc}") from exc
    if isinstance(policy, type):
        raise ParcoverError(f"policy '{label}': {call} returned the class {policy.__name__}, not a Policy object "
                            "(return an instance)")
    missing = _missing(policy)
    if missing:
        raise ParcoverError(f"policy '{label}': {call} returned {type(policy).__name__}, not a Policy (it has no "
                            f"{', '.join(missing)}; subclass parcover_env.policies.Policy)")
    return policy


def _shown(args: tuple) -> str:
    return ", ".join(("env", "seed")[: len(args)])


def _signature(obj: Any) -> inspect.Signature:
    """``obj``'s call signature; a class without an ``__init__`` of its own below ``object`` or a
    ``typing.Protocol`` (whose stand-in reads ``(*args, **kwargs)``) takes no arguments."""
    if isinstance(obj, type):
        for klass in obj.__mro__:
            init = klass.__dict__.get("__init__")
            if init is None:
                continue
            if init is object.__init__ or getattr(init, "__name__", "") == "_no_init_or_replace_init":
                return inspect.Signature()
            break
    return inspect.signature(obj)


def _arguments(obj: Any, env, seed: int | None, label: str) -> tuple:
    try:
        sig = _signature(obj)
    except (TypeError, ValueError):  # no signature to read (some builtins): the documented call
        return (env, seed)
    for args in ((env, seed), (env,), ()):
        try:
            sig.bind(*args)
        except TypeError:
            continue
        return args
    raise ParcoverError(f"policy '{label}': {_name(obj)}{sig} takes neither (env, seed), (env) nor no arguments")


def env_overrides_of(obj: Any, label: str) -> dict | None:
    """The ``env_overrides`` mapping attribute of a factory, class or object (None without one);
    ParcoverError if it is not a mapping."""
    overrides = getattr(obj, "env_overrides", None)
    if overrides is not None and not isinstance(overrides, dict):
        raise ParcoverError(f"policy '{label}': env_overrides must be a mapping, got {type(overrides).__name__}")
    return overrides or None
