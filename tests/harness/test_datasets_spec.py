"""Minari datasets record a usable env_spec: the one-robot Gymnasium env of the scenario."""

from __future__ import annotations

import gymnasium as gym

import parcover_env
from parcover_env.harness.datasets import _env_spec


def test_env_spec_rebuilds_a_one_robot_env_by_scenario_name():
    spec = _env_spec(parcover_env.parallel_env("t_room"))
    assert spec.id == "parcover_env/SingleRobotCoverage-v0"
    assert spec.kwargs == {"scenario": "t_room", "overrides": {"n_robots": 1}}  # a name, not a machine path
    env = gym.make(spec)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs) and spec.max_episode_steps == env.unwrapped.par.max_cycles
    assert gym.envs.registration.EnvSpec.from_json(spec.to_json()) == spec
