"""The ``py:MODULE:ATTR`` policy spec: a policy defined outside the package, built by the registry
(and so by ``parcover run``, ``bench`` and ``collect``); every problem is one ParcoverError, pinned."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import parcover_env
from parcover_env.errors import ParcoverError
from parcover_env.policies import Policy, check_policy_spec, make_policy
from parcover_env.policies.external import policy_from
from parcover_env.policies.registry import policy_overrides

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"


@pytest.fixture(autouse=True)
def user_module_on_path(monkeypatch):
    monkeypatch.syspath_prepend(str(FIXTURES))


@pytest.fixture(scope="module")
def env():
    return parcover_env.parallel_env("office")


def _error(spec: str, env=None) -> str:
    with pytest.raises(ParcoverError) as info:
        if env is None:
            check_policy_spec(spec)
        else:
            make_policy(spec, env, 0)
    return str(info.value)


def test_a_factory_a_class_and_their_env_overrides(env):
    import user_policies

    still = make_policy("py:user_policies:make_still", env, 5)  # factory (env, seed)
    assert type(still) is user_policies.StandStill
    obs, _ = env.reset(seed=5)
    assert {a: v.tolist() for a, v in still.act(obs).items()} == {"robot_0": [0.0, 0.0], "robot_1": [0.0, 0.0]}
    a = make_policy("py:user_policies:SeededRandom", env, 7)  # a class built as (env, seed): the seed reaches it
    b = make_policy("py:user_policies:SeededRandom", env, 7)
    c = make_policy("py:user_policies:SeededRandom", env, 8)
    assert np.array_equal(a.act(obs)["robot_0"], b.act(obs)["robot_0"])
    assert not np.array_equal(b.act(obs)["robot_0"], c.act(obs)["robot_0"])
    assert type(make_policy("py:user_policies:StandStill", env, 0)) is user_policies.StandStill  # class ()
    check_policy_spec("py:user_policies:STILL")  # a Policy object (not callable) is used as it is
    assert make_policy("py:user_policies:STILL", env, 0) is user_policies.STILL
    assert policy_overrides("py:user_policies:make_still") is None
    assert policy_overrides("py:user_policies:make_expert", "office") == {
        "observation": {"scan": {"enabled": True, "confirm_widened": True}}}
    assert "py:MODULE:ATTR" in parcover_env.policies.policy_specs().split(" | ")


def test_missing_module():
    assert _error("py:no_such_pkg.agents:make_policy") == (
        "policy 'py:no_such_pkg.agents:make_policy': cannot import module 'no_such_pkg.agents' "
        "(ModuleNotFoundError: No module named 'no_such_pkg'); is the folder that holds it on PYTHONPATH?")


def test_missing_attribute():
    assert _error("py:user_policies:make_polcy") == (
        "policy 'py:user_policies:make_polcy': 'user_policies' has no attribute 'make_polcy'")
    assert _error("py:user_policies:StandStill.nope") == (
        "policy 'py:user_policies:StandStill.nope': 'user_policies.StandStill' has no attribute 'nope'")
    assert _error("py:user_policies:StandStill.act.nope") == (
        "policy 'py:user_policies:StandStill.act.nope': 'user_policies.StandStill.act' has no attribute 'nope'")


def test_malformed_specs():
    msg = "policy '{}': give MODULE:ATTR after 'py:', e.g. py:my_pkg.agents:make_policy"
    for spec in ("py", "py:", "py:user_policies", "py:user_policies:", "py::make"):
        assert _error(spec) == msg.format(spec)
    assert _error("py:my-pkg:make") == "policy 'py:my-pkg:make': 'my-pkg' is not a module path (dotted Python names)"
    assert _error("py:user_policies:make still") == (
        "policy 'py:user_policies:make still': 'make still' is not an attribute name")
    assert _error("py:user_policies:make:still") == (
        "policy 'py:user_policies:make:still': 'make:still' is not an attribute name")


def test_not_callable():
    assert _error("py:user_policies:NOT_CALLABLE") == (
        "policy 'py:user_policies:NOT_CALLABLE': int is not callable: give a factory (env, seed) -> Policy, "
        "a Policy class or a Policy object")


def test_wrong_return_types(env):
    check_policy_spec("py:user_policies:returns_number")  # callable: what it returns is seen when it is called
    assert _error("py:user_policies:returns_number", env) == (
        "policy 'py:user_policies:returns_number': returns_number(env, seed) returned int, not a Policy (it has no "
        "act, reset, stats, belief; subclass parcover_env.policies.Policy)")
    assert _error("py:user_policies:returns_act_only", env) == (
        "policy 'py:user_policies:returns_act_only': returns_act_only(env, seed) returned ActOnly, not a Policy "
        "(it has no reset, stats, belief; subclass parcover_env.policies.Policy)")


def test_wrong_observation_shape(env):
    assert _error("py:user_policies:WrongShape", env) == (
        "policy 'py:user_policies:WrongShape' was trained on observations of shape (3,); scenario 'office' gives "
        f"{env.observation_space('robot_0').shape}")


def test_factory_calls_and_their_errors(env):
    """``policy_from``: the call each signature gets, and one error for each way it can go wrong."""
    calls = []

    class Fresh(Policy):  # no __init__ of its own: typing.Protocol's stand-in until the first instance
        def act(self, observations):
            return {}

    class Mine(Fresh):
        pass

    class TakesEnv(Policy):
        def __init__(self, env):
            calls.append(("class", env.scenario.name))

        def act(self, observations):
            return {}

    class Inherits(TakesEnv):
        pass

    def two(env, seed):
        calls.append(("two", seed))
        return Mine()

    def one(env):
        calls.append(("one", env.scenario.name))
        return Mine()

    def default_seed(env, seed=None):
        calls.append(("default", seed))
        return Mine()

    assert type(policy_from(Fresh, env, 4, "x")) is Fresh  # before any instance: the stand-in's (*args, **kwargs)
    assert type(policy_from(Fresh, env, 4, "x")) is Fresh  # after one: object.__init__
    for f in (two, one, default_seed, Mine):
        assert type(policy_from(f, env, 4, "x")) is Mine
    for cls in (TakesEnv, Inherits):
        assert type(policy_from(cls, env, 4, "x")) is cls
    assert calls == [("two", 4), ("one", "office"), ("default", 4), ("class", "office"), ("class", "office")]
    obj = Mine()
    assert policy_from(obj, env, 4, "x") is obj  # a Policy object is used as it is

    class Factory:  # a callable object (no __qualname__): named by its type
        def __call__(self, env, seed):
            return 3

    with pytest.raises(ParcoverError) as info:
        policy_from(Factory(), env, 0, "mine")
    assert str(info.value) == ("policy 'mine': Factory(env, seed) returned int, not a Policy (it has no act, reset, "
                               "stats, belief; subclass parcover_env.policies.Policy)")

    def three(env, seed, extra):
        return Mine()

    with pytest.raises(ParcoverError) as info:
        policy_from(three, env, 0, "mine")
    assert str(info.value) == ("policy 'mine': test_factory_calls_and_their_errors.<locals>.three(env, seed, extra) "
                               "takes neither (env, seed), (env) nor no arguments")

    def broken(env, seed):
        raise KeyError("weights")

    with pytest.raises(ParcoverError) as info:
        policy_from(broken, env, 0, "mine")
    assert str(info.value) == ("policy 'mine': test_factory_calls_and_their_errors.<locals>.broken(env, seed) "
                               "raised KeyError: 'weights'")
    assert isinstance(info.value.__cause__, KeyError)  # the user's traceback stays chained

    with pytest.raises(ParcoverError) as info:
        policy_from(lambda env: Mine, env, 0, "mine")
    assert str(info.value) == ("policy 'mine': test_factory_calls_and_their_errors.<locals>.<lambda>(env) returned "
                               "the class Mine, not a Policy object (return an instance)")
    with pytest.raises(ParcoverError) as info:
        policy_from(3.5, env, 0, "mine")
    assert str(info.value) == ("policy 'mine': float is neither a Policy (with act, reset, stats, belief) nor a "
                               "factory (env, seed) -> Policy")


def test_env_overrides_must_be_a_mapping(monkeypatch):
    import user_policies

    monkeypatch.setattr(user_policies.make_still, "env_overrides", ["observation"], raising=False)
    assert _error("py:user_policies:make_still") == (
        "policy 'py:user_policies:make_still': env_overrides must be a mapping, got list")


def test_a_py_spec_labels_and_drives_recorded_episodes():
    """``parcover collect``'s recorder builds its labeller and its DAgger driver from specs too."""
    from parcover_env.harness.datasets import record_episodes

    eps = record_episodes("office", 1, seed=3, policy="py:user_policies:make_still", max_steps=5,
                          driver="py:user_policies:SeededRandom", driver_prob=1.0)
    still = record_episodes("office", 1, seed=3, policy="py:user_policies:make_still", max_steps=5)
    assert [e["agent"] for e in eps] == [e["agent"] for e in still] == ["robot_0", "robot_1"]
    for e, s in zip(eps, still, strict=True):  # the labeller's zeros are recorded either way
        assert e["actions"].shape == s["actions"].shape == (5, 2) and not e["actions"].any() and not s["actions"].any()
        assert np.array_equal(e["observations"][0], s["observations"][0])
        assert not np.array_equal(e["observations"][-1], s["observations"][-1])  # the random driver moved the team
