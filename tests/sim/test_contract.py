"""The stepper's typed contract (:mod:`parcover_env.sim.contract`): the envs satisfy it, and it names
exactly the attributes the phases of :mod:`parcover_env.sim` use of a world, read from their source."""

from __future__ import annotations

import ast
import copy
import pickle
from pathlib import Path

import numpy as np
import pytest

import parcover_env
from parcover_env.envs.batched import BatchedVecEnv
from parcover_env.sim import contract
from parcover_env.sim.contract import Features, Layout, StepWorld
from parcover_env.sim.score_phase import PARTS

SIM = Path(contract.__file__).resolve().parent
WORLD_NAMES = {"w", "first"}
"""How the phases name a world: a loop variable over ``worlds``, ``first = worlds[0]``."""


def _members(protocol: type) -> set[str]:
    names = set(getattr(protocol, "__annotations__", {}))
    names |= {n for n, v in vars(protocol).items()
              if not n.startswith("_") and (callable(v) or isinstance(v, property))}
    return names


def _world_attributes() -> set[str]:
    """Every attribute the sim's modules read or write of a world: ``w.x``, ``first.x``, ``worlds[k].x``,
    ``getattr(w, "x", ...)`` and the world attributes of the score phase's :data:`PARTS`."""
    found = set()
    for path in SIM.glob("*.py"):
        if path.name == "contract.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute):
                base = node.value
                named = isinstance(base, ast.Name) and base.id in WORLD_NAMES
                indexed = (isinstance(base, ast.Subscript) and isinstance(base.value, ast.Name)
                           and base.value.id == "worlds")
                if named or indexed:
                    found.add(node.attr)
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr"
                  and isinstance(node.args[0], ast.Name) and node.args[0].id in WORLD_NAMES
                  and isinstance(node.args[1], ast.Constant)):
                found.add(node.args[1].value)
    return found | {attr for attr, _ in PARTS.values()}


def test_the_contract_names_exactly_what_the_phases_use():
    used, declared = _world_attributes(), _members(StepWorld)
    assert used - declared == set(), f"the phases use attributes the contract does not name: {used - declared}"
    assert declared - used == set(), f"the contract names attributes no phase uses: {declared - used}"
    assert {"team", "estimator", "progress", "layout", "sensors", "camera", "np_random", "scenario", "map",
            "features"} <= declared


def test_the_contract_is_typed():
    for name in StepWorld.__annotations__:
        assert StepWorld.__annotations__[name] not in ("Any", "object"), name
    assert {"fills", "info"} == set(Features.__annotations__)
    assert {"slices"} == set(Layout.__annotations__) and {"size", "fill_scalars_many", "clip"} <= _members(Layout)


@pytest.mark.parametrize("version", [1, 2])
def test_a_reset_env_is_a_step_world(version):
    env = parcover_env.parallel_env("tree", overrides={"observation": {"version": version}})
    assert not isinstance(env, StepWorld)  # no episode yet: no world, team, estimator, ...
    env.reset(seed=0)
    assert isinstance(env, StepWorld) and isinstance(env.layout, Layout) and isinstance(env.features, Features)
    env.step({a: np.array([0.5, 0.1], dtype=np.float32) for a in env.agents})
    assert isinstance(env, StepWorld)
    for twin in (copy.deepcopy(env), pickle.loads(pickle.dumps(env))):  # copies keep the contract, own their blocks
        assert isinstance(twin, StepWorld) and twin.score_group is None


def test_the_batched_worlds_are_step_worlds():
    batch = BatchedVecEnv("tree", 2)
    batch.seed(0)
    batch.reset()
    batch.step(np.zeros((batch.num_envs, 2), dtype=np.float32))
    assert all(isinstance(w, StepWorld) for w in batch.worlds)
    assert batch.worlds[0].score_group is batch.worlds[1].score_group is not None  # scored together


def test_an_object_missing_one_attribute_is_not_a_step_world():
    env = parcover_env.parallel_env("tree")
    env.reset(seed=0)
    del env.score_state
    assert not isinstance(env, StepWorld)
