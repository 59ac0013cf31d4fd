"""One registry of policies, by spec string: ``NAME`` or ``NAME:PATH`` (``expert``, ``ppo:runs/x``).

:data:`POLICIES` maps a name to a :class:`PolicyEntry`: a factory ``(env, seed, path) -> Policy``
and whether the spec needs a checkpoint path. ``parcover run --policy``, ``parcover bench`` and
``parcover collect`` all build their policies here, so the spec help, the error for an unknown
name and the checks of a spec are written once.

Adding a policy is one entry. Write the class (subclass :class:`~parcover_env.policies.Policy`
for the default ``reset``/``stats``/``belief``) in its own module, then add here::

    "greedy": PolicyEntry(_greedy, "drives to the nearest unvisited KPOI"),

with ``def _greedy(env, seed, path): from parcover_env.policies.greedy import Greedy; return Greedy(env.layout)``
(import inside the factory: heavy dependencies load only when the policy is used). A policy that
loads a checkpoint sets ``needs_path=True`` (:func:`check_policy_spec` then checks that the path
exists) and checks in its factory that the checkpoint's observation shape is the scenario's.
Code outside the package may add an entry to :data:`POLICIES` at run time the same way
(in-process runs only: ``parcover bench`` workers start from the built-in registry), or, to reach
worker processes too, be named by the spec ``py:MODULE:ATTR`` (:mod:`parcover_env.policies.external`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from parcover_env.errors import ArgumentError, ParcoverError
from parcover_env.policies.protocol import Policy

__all__ = ["POLICIES", "PolicyEntry", "BASIC_POLICIES", "POLICY_SPECS", "make_policy", "check_policy_spec",
           "policy_overrides", "policy_specs", "fitting_policy", "REMOVED_POLICIES"]


@dataclass(frozen=True)
class PolicyEntry:
    """How to build one kind of policy."""

    factory: Callable[[Any, int | None, str], Policy]
    """``(env, seed, path) -> Policy``; ``path`` is the text after ``NAME:`` ("" if none)."""
    summary: str
    """One line for ``--help``."""
    needs_path: bool = False
    """The spec is ``NAME:PATH`` with an existing checkpoint path (else plain ``NAME``)."""
    env_overrides: dict | None = None
    """Scenario overrides the env must be built with for this policy (e.g. the ``scan`` action of
    the sonar localization service); ``parcover run`` and ``parcover bench`` apply them."""
    path_overrides: Callable[[str], dict | None] | None = None
    """``path -> overrides``: those of one checkpoint (e.g. read from its sidecar); used instead of
    :attr:`env_overrides` when set."""
    scenario_overrides: Callable[[str], dict | None] | None = None
    """``scenario -> overrides`` (a scenario name or path): used instead of :attr:`env_overrides` when
    the caller names the scenario (:func:`policy_overrides`)."""
    check_path: Callable[[str, str], None] | None = None
    """``(path, spec) -> None``: checks the text after ``NAME:`` (raises ParcoverError naming ``spec``)
    instead of requiring an existing path."""
    path_hint: str = "PATH"
    """What follows ``NAME:`` in the spec help (``NAME:PATH``)."""


@lru_cache(maxsize=256)
def _navigates_by_sonar(scenario: str) -> bool:
    from parcover_env.scenarios import load_scenario

    return load_scenario(scenario).localization == "sonar"


def _expert_overrides(scenario: str) -> dict:
    """The expert's env: the sonar service, and, unless the scenario's expert is the sonar navigator
    (``localization: sonar``), ``confirm_widened``: the formation expert scans from elsewhere after a
    held fix (``expert.sonar_fix.relocate_distance``); the navigator rescans at its route's end in
    place, where a held fix is never confirmed (hallway seeds 8, 10, 14 were lost with it on)."""
    scan: dict = {"enabled": True}
    if not _navigates_by_sonar(scenario):
        scan["confirm_widened"] = True
    return {"observation": {"scan": scan}}


def _random(env, seed: int | None, path: str) -> Policy:
    from parcover_env.policies.simple import RandomPolicy

    return RandomPolicy(seed)


def _waypoint(env, seed: int | None, path: str) -> Policy:
    from parcover_env.policies.simple import WaypointPolicy

    return WaypointPolicy(env.layout)


def _expert(env, seed: int | None, path: str) -> Policy:
    from parcover_env.expert import expert_for

    return expert_for(env)


def _fitting(policy, env, spec: str):
    """``policy`` if its checkpoint's observation shape is ``env``'s, else a ParcoverError naming both."""
    expected = env.observation_space(env.possible_agents[0]).shape
    if tuple(policy.obs_shape) != tuple(expected):
        raise ParcoverError(f"policy '{spec}' was trained on observations of shape "
                            f"{tuple(policy.obs_shape)}; scenario '{env.scenario.name}' gives {tuple(expected)}")
    return policy


def fitting_policy(policy, env, label: str):
    """``policy`` if it declares no ``obs_shape`` or its ``obs_shape`` is ``env``'s observation
    shape, else the ParcoverError of a checkpoint policy that does not fit (the check all share)."""
    if getattr(policy, "obs_shape", None) is None:
        return policy
    return _fitting(policy, env, label)


def _python(env, seed: int | None, path: str) -> Policy:
    from parcover_env.policies.external import PY_PREFIX, load_attribute, policy_from

    spec = f"{PY_PREFIX}:{path}"
    return fitting_policy(policy_from(load_attribute(path, spec), env, seed, spec), env, spec)


def _python_check(path: str, spec: str) -> None:
    from parcover_env.policies.external import check_python_spec

    check_python_spec(path, spec)


def _python_overrides(path: str) -> dict | None:
    from parcover_env.policies.external import env_overrides_of, load_attribute

    return env_overrides_of(load_attribute(path), f"py:{path}")


def _learned(kind: str) -> Callable[[Any, int | None, str], Policy]:
    def build(env, seed: int | None, path: str) -> Policy:
        from parcover_env.errors import require

        torch = require("torch", "train", f"policy '{kind}:{path}'")
        if kind == "ppo":
            require("stable_baselines3", "train", f"policy '{kind}:{path}'", package="stable-baselines3")
        from parcover_env.policies.learned import BCPolicy, PPOPolicy

        torch.set_num_threads(1)  # small MLPs: one thread is fastest and avoids oversubscribing workers
        policy = PPOPolicy(path) if kind == "ppo" else BCPolicy(path)
        return _fitting(policy, env, f"{kind}:{path}")

    return build


def _torchrl(sampled: bool) -> Callable[[Any, int | None, str], Policy]:
    name = "torchrl_sampled" if sampled else "torchrl"

    def build(env, seed: int | None, path: str) -> Policy:
        from parcover_env.errors import require

        torch = require("torch", "train", f"policy '{name}:{path}'")
        from parcover_env.policies.torchrl_policy import TorchRLPolicy

        torch.set_num_threads(1)
        policy = TorchRLPolicy(path, sample_seed=(0 if seed is None else seed) if sampled else None)
        return _fitting(policy, env, f"{name}:{path}")

    return build


def _torchrl_overrides(path: str) -> dict | None:
    from parcover_env.policies.torchrl_policy import checkpoint_overrides

    return checkpoint_overrides(path)


POLICIES: dict[str, PolicyEntry] = {
    "expert": PolicyEntry(_expert, "the scripted expert of the scenario's localization mode; it stops and "
                          "asks the env for sonar scans (the env's sonar localization; a fix found only in a "
                          "widened region is held until a scan from elsewhere agrees)",
                          env_overrides={"observation": {"scan": {"enabled": True}}},
                          scenario_overrides=_expert_overrides),
    "waypoint": PolicyEntry(_waypoint, "each robot drives to its observed route waypoint, alone, and stops "
                            "to scan (the env's sonar localization) when its uncertainty grows",
                            env_overrides={"observation": {"scan": {"enabled": True}}}),
    "random": PolicyEntry(_random, "uniform random actions"),
    "ppo": PolicyEntry(_learned("ppo"), "a saved SB3 PPO model (model.zip + vecnormalize.pkl)", needs_path=True),
    "bc": PolicyEntry(_learned("bc"), "a behaviour-cloned MLP (bc.pt)", needs_path=True),
    "torchrl": PolicyEntry(_torchrl(False), "an IPPO/MAPPO actor from parcover train (DIR/policy.pt; the env "
                           "overrides it was trained with come from DIR/run.json), deterministic: tanh(loc), "
                           "and a Bernoulli scan head's mode (scan iff p > 0.5)",
                           needs_path=True, path_overrides=_torchrl_overrides),
    "torchrl_sampled": PolicyEntry(_torchrl(True), "the same actor with its actions sampled from its TanhNormal "
                                   "(and Bernoulli scan head) as in training (seeded by the episode's seed)",
                                   needs_path=True,
                                   path_overrides=_torchrl_overrides),
    "py": PolicyEntry(_python, "a policy of your own that this process and bench workers import: "
                      "py:MODULE:ATTR, ATTR a factory (env, seed) -> Policy or a Policy class "
                      "(see parcover_env.policies.external)", needs_path=True, path_overrides=_python_overrides,
                      check_path=_python_check, path_hint="MODULE:ATTR"),
}
"""Every policy by name; see the module docstring to add one."""

REMOVED_POLICIES: dict[str, str] = {
    "mappo": "mappo: checkpoints of the removed hand-written trainer (baselines/train_mappo.py) are no longer a "
             "spec; use torchrl: (parcover train mappo writes DIR/policy.pt); an old DIR/actor.pt has the bc: "
             "format and loads as bc:DIR/actor.pt",
}
"""Spec names that no longer exist -> what to use instead (:func:`check_policy_spec` raises it)."""


def policy_specs() -> str:
    """The accepted specs, e.g. ``expert | waypoint | random | ppo:PATH | ... | torchrl_sampled:PATH``."""
    return " | ".join(f"{name}:{e.path_hint}" if e.needs_path else name for name, e in POLICIES.items())


BASIC_POLICIES = tuple(name for name, e in POLICIES.items() if not e.needs_path)
"""The policies that need no checkpoint."""
POLICY_SPECS = policy_specs()
"""The accepted specs as one line (the built-in registry)."""


def check_policy_spec(spec: str) -> None:
    """Raise ParcoverError unless ``spec`` names a registered policy (with an existing path if it needs one)."""
    name, _, path = spec.partition(":")
    entry = POLICIES.get(name)
    if entry is None and name in REMOVED_POLICIES:
        raise ArgumentError(f"policy '{spec}': {REMOVED_POLICIES[name]}")
    if entry is None or (path and not entry.needs_path):
        raise ParcoverError(f"unknown policy '{spec}' (choose from {policy_specs()})")
    if entry.needs_path:
        if entry.check_path is not None:
            entry.check_path(path, spec)
            return
        if not path:
            raise ParcoverError(f"policy '{spec}': give a checkpoint, e.g. {name}:runs/{name}_office")
        if not Path(path).exists():
            raise ParcoverError(f"policy '{spec}': {path} does not exist")


def policy_overrides(spec: str, scenario: str | None = None) -> dict | None:
    """The scenario overrides the env of policy ``spec`` needs (:attr:`PolicyEntry.env_overrides`; with
    ``scenario``, a name or path, :attr:`PolicyEntry.scenario_overrides` where the entry has them)."""
    check_policy_spec(spec)
    name, _, path = spec.partition(":")
    entry = POLICIES[name]
    if entry.path_overrides is not None:
        return entry.path_overrides(path)
    if scenario is not None and entry.scenario_overrides is not None:
        return entry.scenario_overrides(scenario)
    return entry.env_overrides


def make_policy(spec: str, env, seed: int | None) -> Policy:
    """The policy named by ``spec`` for ``env`` (``seed`` seeds a stochastic policy's generator)."""
    check_policy_spec(spec)
    name, _, path = spec.partition(":")
    return POLICIES[name].factory(env, seed, path)
