"""The Policy protocol and the registry dict: every name builds a Policy, one entry adds a policy."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import parcover_env
from parcover_env.errors import ParcoverError
from parcover_env.expert import expert_for
from parcover_env.expert.navigator import SonarNavigator
from parcover_env.expert.scripted import ScriptedExpert
from parcover_env.policies import POLICIES, Policy, PolicyEntry, check_policy_spec, make_policy, policy_specs

PACKAGE = Path(parcover_env.__file__).parent
PROTOCOL = ("act", "reset", "stats", "belief")


class _Still(Policy):
    """Stands still; inherits the protocol's defaults."""

    def act(self, observations):
        return {a: np.zeros(2, dtype=np.float32) for a in observations}


def test_protocol_defaults():
    p = _Still()
    assert isinstance(p, Policy)
    assert p.reset({"robot_0": np.zeros(3)}) is None and p.stats() == {} and p.belief() is None
    assert not isinstance(object(), Policy)  # no act: not a policy


@pytest.mark.parametrize("name", ["expert", "waypoint", "random"])
def test_every_plain_name_builds_a_policy(name):
    env = parcover_env.parallel_env("t_room")
    policy = make_policy(name, env, 3)
    assert isinstance(policy, Policy)
    obs, _ = env.reset(seed=3)
    policy.reset(obs)
    act = policy.act(obs)
    assert set(act) == set(obs) and all(a.shape == (2,) and np.all(np.abs(a) <= 1) for a in act.values())


def test_expert_for_picks_the_expert_of_the_localization_mode():
    office = parcover_env.parallel_env("office")
    hallway = parcover_env.parallel_env("hallway")  # localization: sonar
    assert type(expert_for(office)) is ScriptedExpert
    assert type(expert_for(hallway)) is SonarNavigator
    assert isinstance(expert_for(hallway), Policy)  # structurally: reset, act, stats, belief
    assert type(ScriptedExpert.for_env(hallway)) is ScriptedExpert  # for_env builds its own class, always


def test_one_entry_adds_a_policy(monkeypatch, capsys):
    monkeypatch.setitem(POLICIES, "still", PolicyEntry(lambda env, seed, path: _Still(), "stands still"))
    check_policy_spec("still")
    assert "still" in policy_specs().split(" | ")
    env = parcover_env.parallel_env("t_room")
    assert isinstance(make_policy("still", env, 0), _Still)
    with pytest.raises(ParcoverError, match="unknown policy 'still:x'"):  # takes no path
        check_policy_spec("still:x")
    from parcover_env.cli.main import build_parser  # the command line's help lists it too

    for command in ("run", "bench"):
        with pytest.raises(SystemExit):
            build_parser().parse_args([command, "--help"])
        help_text = " ".join(capsys.readouterr().out.split())
        assert ("random | ppo:PATH | bc:PATH | torchrl:PATH | torchrl_sampled:PATH | py:MODULE:ATTR "
                "| still") in help_text


def test_specs_and_errors():
    assert policy_specs() == ("expert | waypoint | random | ppo:PATH | bc:PATH | torchrl:PATH | torchrl_sampled:PATH | "
                              "py:MODULE:ATTR")
    with pytest.raises(ParcoverError, match=r"unknown policy 'greedy' \(choose from expert \| waypoint"):
        check_policy_spec("greedy")
    with pytest.raises(ParcoverError, match="give a checkpoint"):
        check_policy_spec("ppo")
    with pytest.raises(ParcoverError, match="does not exist"):
        check_policy_spec("bc:/nonexistent/bc.pt")


def test_no_duck_typed_policy_calls():
    """The harness calls the protocol's methods; nothing asks ``hasattr(policy, ...)``."""
    roots = [PACKAGE, PACKAGE.parent / "baselines"]
    found = []
    for root in roots:
        for path in root.rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "hasattr"
                        and len(node.args) == 2 and getattr(node.args[1], "value", None) in PROTOCOL):
                    found.append(f"{path.name}:{node.lineno}")
    assert found == []
