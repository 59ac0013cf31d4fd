"""The optional ``contact`` reward term: per step a robot touches a wall or robot, pinned by value on
hand-built situations; with its weight 0 (the default) the env has no such term at all."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env import parcover_v2
from parcover_env.config import RewardConfig
from parcover_env.errors import ConfigError
from parcover_env.mission.rewards import TERMS, TERMS_V2, RewardInputs, paid_terms, reward_terms, touching

WALL = np.array([[0.0, 0.0, 4.0, 0.0]])  # the x axis from 0 to 4 m


def test_touching_walls_by_distance_to_the_nearest_segment():
    xy = np.array([[1.0, 0.215], [3.0, 0.225], [5.0, 0.21]])  # r 0.2, gap 0.02: 0.215 < 0.22 < 0.225
    # robot 2 lies beyond the segment's end: its distance is to the end point (1, 0.21) -> 1.02
    np.testing.assert_array_equal(touching(xy, WALL, 0.2, 0.02), [1.0, 0.0, 0.0])
    np.testing.assert_array_equal(touching(xy, WALL, 0.2, 0.03), [1.0, 1.0, 0.0])  # the gap is used
    np.testing.assert_array_equal(touching(xy[:1], np.empty((0, 4)), 0.2, 0.02), [0.0])  # no walls


def test_touching_robots_counts_both_and_never_a_robot_with_itself():
    xy = np.array([[1.0, 2.0], [1.41, 2.0], [3.0, 2.0]])  # 0 and 1: 0.41 apart, under 2 r + gap = 0.42
    np.testing.assert_array_equal(touching(xy, WALL, 0.2, 0.02), [1.0, 1.0, 0.0])
    np.testing.assert_array_equal(touching(xy, WALL, 0.2, 0.005), [0.0, 0.0, 0.0])  # 0.41 > 0.405
    np.testing.assert_array_equal(touching(xy[:1], WALL, 0.2, 0.02), [0.0])  # alone, far from the wall


def test_reward_terms_pay_the_contact_weight_per_touching_step_last():
    w = RewardConfig(contact=-0.3)
    t = reward_terms(w, paid_terms(TERMS_V2, w), RewardInputs(0, np.zeros(3), np.zeros(3, int), np.zeros(3),
                                                              touch=np.array([1.0, 0.0, 1.0])))
    assert list(t) == [*TERMS_V2, "contact"]
    np.testing.assert_array_equal(t["contact"], [-0.3, 0.0, -0.3])
    block = reward_terms(w, ("contact",), RewardInputs(np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2), int),
                                                      touch=np.array([[0.0, 1.0], [1.0, 1.0]])))
    np.testing.assert_array_equal(block["contact"], [[0.0, -0.3], [-0.3, -0.3]])  # K worlds
    assert "contact" not in paid_terms(TERMS_V2, RewardConfig(uncertainty=1.0))
    none = RewardConfig()  # weight 0: no term
    assert paid_terms(TERMS, none) == TERMS and paid_terms(TERMS_V2, none) == TERMS_V2


def test_contact_gap_must_be_positive():
    with pytest.raises(ConfigError, match="contact_gap"):
        RewardConfig(contact_gap=0.0)


def _env(contact: float):
    rewards = {"contact": contact} if contact else {}
    return parcover_v2.parallel_env("office", preset="ideal", overrides={
        "observation": {"pose_source": "ground_truth"}, "rewards": rewards})


def _stand(env):
    return {a: np.zeros(2, np.float32) for a in env.agents}


def _against_a_wall(env, gap: float) -> None:
    """Robot 0 ``gap`` off the middle of the map's longest wall, on the side of robot 0's start."""
    seg = max(env.map.segments, key=lambda s: np.hypot(s[2] - s[0], s[3] - s[1]))
    a, b = seg[:2], seg[2:]
    mid = (a + b) / 2
    normal = np.array([-(b - a)[1], (b - a)[0]]) / np.linalg.norm(b - a)
    start = np.asarray(env.world.bodies[0].position)
    normal *= np.sign(np.dot(start - mid, normal)) or 1.0
    env.world.bodies[0].position = tuple(mid + normal * (env.world.radius + gap))


def test_env_pays_contact_every_step_the_robot_stays_against_the_wall():
    env = _env(-0.5)
    env.reset(seed=0)
    assert env.terms == (*TERMS_V2, "contact")
    _against_a_wall(env, 0.005)
    for _ in range(3):  # standing against the wall: paid each step, not only at the first
        _, rew, _, _, infos = env.step(_stand(env))
        assert [infos[a]["reward_contact"] for a in env.possible_agents] == [-0.5, 0.0]
        for a in env.possible_agents:
            assert rew[a] == pytest.approx(sum(infos[a][f"reward_{t}"] for t in env.terms), abs=1e-12)


def test_env_without_contact_weight_has_no_contact_term():
    env = _env(0.0)
    env.reset(seed=0)
    _against_a_wall(env, 0.005)
    _, _, _, _, infos = env.step(_stand(env))
    assert env.terms == TERMS_V2 and "reward_contact" not in infos["robot_0"]
