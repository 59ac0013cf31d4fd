"""Action faults at env level, on every shipped scenario: malformed joint actions raise ActionError
and leave the state untouched; out-of-range values behave exactly as if they had been clipped."""

from __future__ import annotations

import numpy as np
import pytest
from reliability_helpers import (
    assert_same_records,
    assert_same_snapshot,
    random_actions,
    snapshot,
    step_record,
)

import parcover_env as pe
from parcover_env.errors import ActionError, ParcoverError

SCENARIOS = pe.scenario_names()


@pytest.fixture(scope="module", params=SCENARIOS)
def env_pair(request):
    """Two independent envs of one scenario (the second is the reference twin)."""
    return pe.parallel_env(request.param), pe.parallel_env(request.param)


def _start(pair, seed: int = 11, warmup: int = 5):
    a, b = pair
    a.reset(seed=seed)
    b.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(warmup):
        acts = random_actions(a.agents, rng)
        a.step(acts)
        b.step(acts)
    return a, b


def _bad_joint_actions(agents: list[str]) -> dict[str, dict]:
    ok = {x: np.zeros(2, np.float32) for x in agents}
    first = agents[0]
    cases = {
        "nan": {first: np.array([np.nan, 0.0])},
        "+inf": {first: np.array([np.inf, 0.0])},
        "-inf": {first: np.array([0.0, -np.inf])},
        "shape (3,)": {first: np.zeros(3)},
        "shape (1,)": {first: np.zeros(1)},
        "shape (2, 1)": {first: np.zeros((2, 1))},
        "scalar": {first: 0.5},
        "string": {first: "forward"},
        "None": {first: None},
        "complex": {first: np.array([1j, 0.0])},
        "nested list": {first: [[0.1, 0.2], [0.3, 0.4]]},
    }
    out = {k: {**ok, **v} for k, v in cases.items()}
    out["missing agent"] = {x: ok[x] for x in agents[1:]}
    out["extra agent"] = {**ok, "robot_99": np.zeros(2)}
    out["int keys"] = {i: ok[x] for i, x in enumerate(agents)}
    out["empty dict"] = {}
    out["list instead of dict"] = [ok[x] for x in agents]
    out["array instead of dict"] = np.zeros((len(agents), 2))
    out["None"] = None
    return out


def test_malformed_actions_raise_and_leave_state_untouched(env_pair):
    a, b = _start(env_pair)
    for name, bad in _bad_joint_actions(a.agents).items():
        before = snapshot(a)
        with pytest.raises(ActionError) as info:
            a.step(bad)
        assert isinstance(info.value, ParcoverError) and str(info.value), name
        assert_same_snapshot(before, snapshot(a))
    # the twin never saw the bad actions: both must now continue identically
    rng = np.random.default_rng(5)
    recs_a, recs_b = [], []
    for _ in range(20):
        if not a.agents:
            break
        acts = random_actions(a.agents, rng)
        recs_a.append(step_record(a.step(acts)))
        recs_b.append(step_record(b.step(acts)))
    assert_same_records(recs_a, recs_b)
    assert_same_snapshot(snapshot(a), snapshot(b))


def test_error_names_the_agent(env_pair):
    a, _ = _start(env_pair, warmup=0)
    agent = a.agents[-1]
    acts = {x: np.zeros(2) for x in a.agents}
    acts[agent] = np.array([0.0, np.nan])
    with pytest.raises(ActionError, match=agent):
        a.step(acts)


@pytest.mark.parametrize("scale", [1.5, 10.0, 1e6, 3.4e38])
def test_out_of_range_is_clipped_exactly(env_pair, scale):
    """Out-of-range actions: same trajectory as the explicitly clipped actions (documented clip)."""
    a, b = _start(env_pair, seed=3)
    rng = np.random.default_rng(int(scale) % 1000)
    recs_a, recs_b = [], []
    for _ in range(25):
        if not a.agents:
            break
        raw = random_actions(a.agents, rng, scale=scale)
        recs_a.append(step_record(a.step(raw)))
        recs_b.append(step_record(b.step({k: np.clip(v, -1.0, 1.0) for k, v in raw.items()})))
    assert_same_records(recs_a, recs_b)
    assert_same_snapshot(snapshot(a), snapshot(b))
    assert np.all(np.abs(a.commands) <= [a.scenario.robot.max_speed, a.scenario.robot.max_turn_rate])


def test_accepted_action_containers(env_pair):
    """Lists, tuples, float32/float64/int arrays are all accepted and mean the same thing."""
    a, b = _start(env_pair, seed=4)
    forms = [lambda v: list(map(float, v)), tuple, lambda v: np.asarray(v, np.float64),
             lambda v: np.asarray(v, np.float32)]
    for form in forms:
        if not a.agents:
            break
        acts = {x: np.array([1.0, -1.0]) for x in a.agents}
        ra = step_record(a.step({x: form(v) for x, v in acts.items()}))
        rb = step_record(b.step(acts))
        assert_same_records([ra], [rb])
    ints = {x: np.array([1, -1]) for x in a.agents}
    floats = {x: v.astype(float) for x, v in ints.items()}
    assert_same_records([step_record(a.step(ints))], [step_record(b.step(floats))])


def test_caller_mutating_action_after_step_changes_nothing(env_pair):
    a, b = _start(env_pair, seed=6)
    acts = {x: np.array([0.7, 0.2]) for x in a.agents}
    a.step(acts)
    b.step({x: v.copy() for x, v in acts.items()})
    for v in acts.values():
        v[:] = np.nan  # the env must not keep a reference to the caller's arrays
    assert_same_snapshot(snapshot(a), snapshot(b))


def test_step_after_episode_end_is_refused():
    env = pe.parallel_env("t_room", overrides={"episode": {"max_steps": 3}})
    env.reset(seed=0)
    for _ in range(3):
        env.step({x: np.zeros(2) for x in env.agents})
    assert env.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        env.step({"robot_0": np.zeros(2)})
