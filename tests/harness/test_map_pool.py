"""The map pool (training on a distribution of generated maps) and a checkpoint's env overrides."""

from __future__ import annotations

import json

import numpy as np
import pytest

import parcover_env
from parcover_env.envs.observations import ObservationLayout
from parcover_env.errors import ConfigError, ParcoverError
from parcover_env.harness.map_pool import POOL_BOX, MapPoolEnv, is_pool, parse_pool

V2 = {"observation": {"version": 2}, "rewards": {"own_kpoi": 10.0, "kpoi": 1.0}}


def test_pool_names_and_the_evaluation_seeds_are_refused():
    assert is_pool("generated:0-499") and not is_pool("generated:7") and not is_pool("office")
    assert parse_pool("generated:3-5") == (3, 4, 5)
    assert parse_pool("generated:999-999") == (999,)
    for bad in ("generated:5-3", "generated:a-3", "generated:-3"):
        with pytest.raises(ConfigError, match="generated:A-B"):
            parse_pool(bad)
    with pytest.raises(ConfigError, match="evaluation maps"):
        parse_pool("generated:990-1000")


@pytest.fixture(scope="module")
def pool():
    return MapPoolEnv("generated:3-4", max_robots=5, overrides=V2, max_cycles=40)  # both maps: 3 robots


def test_padding_agents_are_zero_and_ignored_real_ones_are_the_maps_env(pool):
    assert pool.possible_agents == [f"robot_{i}" for i in range(5)]
    obs, infos = pool.reset(seed=11)
    inner = parcover_env.parallel_env(f"generated:{pool.map_seed}", overrides=V2, max_cycles=40)
    # the pool reset the drawn map's env with a seed from its own generator: replay it on a fresh env
    rng = np.random.default_rng(11)
    rng.choice(pool.seeds)
    inner_obs, _ = inner.reset(seed=int(rng.integers(2**31)))
    assert inner.n_robots == 3
    for i in range(3):
        np.testing.assert_array_equal(obs[f"robot_{i}"], inner_obs[f"robot_{i}"])
        assert infos[f"robot_{i}"]["pad"] == 0.0
    for i in (3, 4):
        assert not obs[f"robot_{i}"].any() and infos[f"robot_{i}"]["pad"] == 1.0
        assert infos[f"robot_{i}"]["route_done"] == 0.0
    act = {a: np.array([0.8, 0.1], np.float32) for a in pool.possible_agents}
    wild = dict(act, robot_3=np.array([-1.0, 1.0], np.float32), robot_4=np.array([1.0, -1.0], np.float32))
    obs, rew, term, trunc, infos = pool.step(wild)
    inner_obs, inner_rew, *_ = inner.step({a: act[a] for a in inner.possible_agents})
    for i in range(3):  # the padding's actions change nothing
        np.testing.assert_array_equal(obs[f"robot_{i}"], inner_obs[f"robot_{i}"])
        assert rew[f"robot_{i}"] == inner_rew[f"robot_{i}"]
    assert rew["robot_3"] == rew["robot_4"] == 0.0 and not obs["robot_4"].any()
    assert set(term) == set(trunc) == set(pool.possible_agents) and not any(term.values())
    assert infos["robot_4"]["metrics/path_lengths"].shape == (5,)
    assert infos["robot_4"]["reward_progress"] == 0.0 and infos["robot_0"]["reward_progress"] != 0.0


def test_episode_ends_for_every_agent_and_the_maps_are_drawn_from_the_pool(pool):
    drawn = set()
    for episode in range(6):
        pool.reset(seed=episode)
        drawn.add(pool.map_seed)
        for _ in range(40):
            out = pool.step({a: np.zeros(2, np.float32) for a in pool.agents})
            if pool.agents == []:
                break
        assert all(out[3].values()) and pool.agents == []  # truncated at 40 steps, all 5 agents
    assert drawn == {3, 4}


def test_observation_box_and_state_are_those_of_the_pool_box(pool):
    layout = ObservationLayout.build(pool.scenario, POOL_BOX, pool.env.sensors)
    space = pool.observation_space("robot_4")
    np.testing.assert_array_equal(space.low, layout.low)
    np.testing.assert_array_equal(space.high, layout.high)
    x = layout.slices["x"]
    assert space.low[x][0] == -1.0 and space.high[x][0] == 15.0  # 14 m plus the 1 m margin
    pool.reset(seed=0)
    assert pool.state().shape == pool.state_space.shape == (322,)


def test_a_map_with_more_robots_than_the_pool_takes_is_refused():
    with pytest.raises(ConfigError, match="max_robots 2"):
        MapPoolEnv("generated:3-3", max_robots=2, overrides=V2)


def test_a_torchrl_checkpoint_brings_the_env_overrides_of_its_run(tmp_path):
    from parcover_env.policies.registry import policy_overrides
    from parcover_env.policies.torchrl_policy import checkpoint_overrides

    (tmp_path / "policy.pt").write_bytes(b"")
    assert policy_overrides(f"torchrl:{tmp_path}/policy.pt") is None  # no sidecar: the scenario as is
    (tmp_path / "run.json").write_text(json.dumps({"algo": "ippo", "env_overrides": V2}))
    assert policy_overrides(f"torchrl:{tmp_path}/policy.pt") == V2
    assert checkpoint_overrides(tmp_path) == V2
    (tmp_path / "run.json").write_text(json.dumps({"env_overrides": {}}))
    assert checkpoint_overrides(tmp_path) is None
    (tmp_path / "run.json").write_text(json.dumps({"env_overrides": [1]}))
    with pytest.raises(ParcoverError, match="must be a mapping"):
        checkpoint_overrides(tmp_path)
    (tmp_path / "run.json").write_text("{not json")
    with pytest.raises(ParcoverError, match="cannot read the sidecar"):
        checkpoint_overrides(tmp_path / "policy.pt")
