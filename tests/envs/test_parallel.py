"""ParallelCoverageEnv: PettingZoo API compliance, determinism, free space, bad input."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test

import parcover_env
from parcover_env.errors import ActionError, ConfigError
from parcover_env.mission.metrics import episode_metrics

SCENARIOS = ["office", "tree", "hallway", "t_room"]


@pytest.fixture(scope="module")
def envs():
    return {name: parcover_env.parallel_env(name) for name in SCENARIOS}


@pytest.mark.parametrize("name", SCENARIOS)
def test_parallel_api(name):
    parallel_api_test(parcover_env.parallel_env(name), num_cycles=200)


@pytest.mark.parametrize("name", SCENARIOS)
def test_aec_api(name):
    api_test(parcover_env.env(name), num_cycles=50)




def _rollout(env, seed, steps, action_seed):
    rng = np.random.default_rng(action_seed)
    obs, infos = env.reset(seed=seed)
    trace = [(copy.deepcopy(obs), None, None)]
    for _ in range(steps):
        if not env.agents:
            obs, infos = env.reset()
        actions = {a: rng.uniform(-1, 1, 2) for a in env.agents}
        obs, rew, term, trunc, infos = env.step(actions)
        trace.append((copy.deepcopy(obs), rew, infos))
    return trace


def _same(a, b) -> bool:
    for (o1, r1, i1), (o2, r2, i2) in zip(a, b):
        if o1.keys() != o2.keys() or any(not np.array_equal(o1[k], o2[k]) for k in o1):
            return False
        if r1 != r2 or repr(i1) != repr(i2):
            return False
    return len(a) == len(b)


@pytest.mark.parametrize("name", ["office", "tree"])
def test_same_seed_bit_identical_different_seed_differs(name):
    t1 = _rollout(parcover_env.parallel_env(name), 7, 200, 1)
    t2 = _rollout(parcover_env.parallel_env(name), 7, 200, 1)
    assert _same(t1, t2)
    t3 = _rollout(parcover_env.parallel_env(name), 8, 200, 1)
    assert not _same(t1, t3)


def test_reset_without_seed_continues_the_generator():
    env = parcover_env.parallel_env("office")
    a = _rollout(env, 3, 30, 0)
    b = _rollout(env, None, 30, 0)  # second episode: noise continues, so it differs
    assert not _same(a, b)


def test_observations_do_not_depend_on_render_mode():
    plain = _rollout(parcover_env.parallel_env("office"), 5, 60, 2)
    drawn_env = parcover_env.parallel_env("office", render_mode="rgb_array")
    drawn = _rollout(drawn_env, 5, 60, 2)
    assert _same(plain, drawn)
    frame = drawn_env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    # robots moved, so their observed poses changed
    first, last = plain[0][0]["robot_0"], plain[-1][0]["robot_0"]
    assert not np.allclose(first[:2], last[:2])


@pytest.mark.parametrize("name", SCENARIOS)
def test_robots_stay_in_free_space_under_random_max_speed_actions(name):
    env = parcover_env.parallel_env(name, overrides={"episode": {"max_steps": 2500}})
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    margin = env.scenario.robot.radius * 0.5  # centre never closer to a wall than half a radius
    worst = np.inf
    for _ in range(10_000):
        if not env.agents:
            env.reset()
        a = rng.uniform(-1, 1, (len(env.agents), 2))
        a[:, 0] = np.sign(a[:, 0])  # full speed forward or backward
        env.step(dict(zip(env.agents, a)))
        xy = env.world.poses()[:, :2]
        assert env.map.contains(xy).all(), f"{name}: a robot centre left free space"
        worst = min(worst, float(np.min(__import__("shapely").distance(env.map.free.boundary,
                                                                         __import__("shapely").points(xy)))))
    assert worst > margin


def test_bad_action_raises_and_leaves_state_untouched():
    ref, env = parcover_env.parallel_env("office"), parcover_env.parallel_env("office")
    ref.reset(seed=1)
    env.reset(seed=1)
    good = {a: np.array([0.5, 0.2]) for a in env.agents}
    with pytest.raises(ActionError, match="robot_1: action contains NaN"):
        env.step({"robot_0": np.array([0.5, 0.2]), "robot_1": np.array([np.nan, 0.0])})
    o1 = ref.step(good)[0]
    o2 = env.step(good)[0]
    assert all(np.array_equal(o1[a], o2[a]) for a in o1)


def test_out_of_range_actions_are_clipped():
    a, b = parcover_env.parallel_env("office"), parcover_env.parallel_env("office")
    a.reset(seed=2)
    b.reset(seed=2)
    oa = a.step({k: np.array([5.0, -9.0]) for k in a.agents})[0]
    ob = b.step({k: np.array([1.0, -1.0]) for k in b.agents})[0]
    assert all(np.array_equal(oa[k], ob[k]) for k in oa)


def test_team_that_does_not_fit_is_a_config_error():
    with pytest.raises(ConfigError, match="n_robots: only"):
        parcover_env.parallel_env("office", overrides={"n_robots": 60})


def test_state_and_spaces(envs):
    env = envs["tree"]
    obs, infos = env.reset(seed=0)
    assert len(env.agents) == env.n_robots == 15
    for a in env.agents:
        assert env.observation_space(a).contains(obs[a])
        assert env.observation_space(a) is env.observation_space(env.agents[0])
        assert infos[a]["reward_kpoi"] == 0.0 and infos[a]["metrics/ended"] == 0.0
    st = env.state()
    assert st.shape == env.state_space.shape and np.all(np.isfinite(st))


def test_episode_end_reports_metrics_and_rewards_terms():
    env = parcover_env.parallel_env("office", overrides={"episode": {"max_steps": 5}})
    env.reset(seed=0)
    for _ in range(5):
        obs, rew, term, trunc, infos = env.step({a: np.zeros(2) for a in env.agents})
        for a, info in infos.items():
            terms = [info[f"reward_{t}"] for t in ("kpoi", "progress", "time", "collision")]
            assert rew[a] == pytest.approx(sum(terms))
    assert all(trunc.values()) and not any(term.values())
    m = episode_metrics(infos["robot_0"])
    assert m["steps"] == 5 and m["kpois_visited"] == 0 and m["success"] is False
    assert env.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})
