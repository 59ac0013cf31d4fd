"""The score and outputs phases through the env, pinned on hand-built situations: contacts counted
over several steps, the true velocity, the render trails, the splits by plan progress past a
lead-in (Min, Fehr & Papanikolopoulos Alg. 1), the hand-over of a promoted follower, the episode's
end and the exact values of the PettingZoo dicts."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.envs.vec_env import make_vec_env
from parcover_env.sim.score_phase import ScoreState


def _office(**kw):
    overrides = {"observation": {"pose_source": "ground_truth"},
                 "rewards": {"kpoi": 10.0, "progress": 2.0, "time": -0.05, "collision": -3.0}}
    overrides.update(kw.pop("overrides", {}))
    return parcover_env.parallel_env("office", preset="ideal", overrides=overrides, **kw)


def _still(env):
    return {a: np.zeros(2, np.float32) for a in env.agents}


def test_collision_term_counts_each_steps_new_wall_and_robot_contacts():
    env = _office()
    env.reset(seed=0)
    env.world.wall_contacts[1] += 2
    env.world.robot_contacts[0] += 1
    _, _, _, _, infos = env.step(_still(env))
    assert [infos[a]["reward_collision"] for a in env.possible_agents] == [-3.0, -6.0]
    env.world.wall_contacts[1] += 1
    _, _, _, _, infos = env.step(_still(env))
    assert [infos[a]["reward_collision"] for a in env.possible_agents] == [0.0, -3.0]
    env.world.robot_contacts[0] += 2
    _, _, _, _, infos = env.step(_still(env))
    assert [infos[a]["reward_collision"] for a in env.possible_agents] == [-6.0, 0.0]
    assert env.score_state.contacts[0].tolist() == [0, 3] and env.score_state.contacts[1].tolist() == [3, 0]


def test_true_velocity_is_the_true_displacement_over_the_control_step_and_trails_grow():
    env = _office(render_mode="rgb_array")
    env.reset(seed=0)
    before = env.world.poses()
    env.step({a: np.array([1.0, 0.3], np.float32) for a in env.agents})
    after = env.world.poses()
    dt = env.scenario.physics.control_dt
    np.testing.assert_allclose(env.true_velocity, (after[:, :2] - before[:, :2]) / dt, rtol=0, atol=1e-12)
    assert np.abs(env.true_velocity).max() > 0.01
    for trail, b, a in zip(env.trails, before, after, strict=True):
        assert len(trail) == 2 and trail[0].tolist() == b[:2].tolist() and trail[1].tolist() == a[:2].tolist()


def test_pettingzoo_dicts_hold_exact_values_and_the_episode_end_clears_the_agents():
    env = _office(overrides={"episode": {"max_steps": 2}})
    env.reset(seed=0)
    agents = list(env.agents)
    _, rew, term, trunc, infos = env.step(_still(env))
    assert term == dict.fromkeys(agents, False) and trunc == dict.fromkeys(agents, False)
    assert all(v is False for v in [*term.values(), *trunc.values()])
    assert all("active" not in info for info in infos.values())
    assert rew == {a: pytest.approx(sum(infos[a][k] for k in infos[a] if k.startswith("reward_"))) for a in agents}
    _, _, term, trunc, infos = env.step(_still(env))
    assert term == dict.fromkeys(agents, False) and all(v is True for v in trunc.values()) and len(trunc) == 2
    assert env.agents == [] and all(infos[a]["metrics/ended"] == 1.0 for a in agents)


def test_score_state_starts_as_float_metres_and_integer_counts():
    s = ScoreState.start([3, 4])
    assert s.remaining.dtype == float and s.wall.dtype == np.int64 and s.robot.dtype == np.int64
    s.remaining[0] = 2.5  # a potential in metres keeps its fraction
    assert s.remaining.tolist() == [2.5, 4.0] and s.contacts[0].tolist() == [0, 0]


def _tree_split():
    """The tree scenario after its first split at TP 0 (the Kinects detect the leader there)."""
    env = parcover_env.parallel_env("tree", preset="ideal")
    env.reset(seed=0)
    env.world.bodies[0].position = tuple(env.plan.turning_points[0].position)
    env.step(_still(env))
    return env


def test_a_split_hands_the_promoted_follower_to_the_kinects():
    env = _tree_split()
    assert env.team.groups == [(10, 15), (0, 5), (5, 10)] and env.team.splits == {"kinect": 1}
    assert sorted(env.kinects.handover) == [10]


@pytest.mark.parametrize("past", [False, True])
def test_a_leader_splits_when_its_plan_progress_past_its_lead_in_reaches_the_tp(past):
    env = _tree_split()
    lead_in, tp_distance = env.progress.offsets[10], env.team.tp_ahead[10, 2]
    assert lead_in > 1.0
    env.progress.progress[10] = lead_in + tp_distance + (0.01 if past else -1.0)  # route arc, lead-in included
    env.step(_still(env))
    assert ((10, 15) in env.team.groups) is not past
    assert env.team.splits == ({"kinect": 1, "odometry": 1} if past else {"kinect": 1})


def test_a_batched_vec_envs_infos_are_active():
    venv = make_vec_env("office", n_envs=2, backend="batched", monitor=False)
    venv.reset()
    _, _, _, infos = venv.step(np.zeros((2 * venv.n_robots, 2), np.float32))
    assert len(infos) == 2 * venv.n_robots and all(i["active"] is True for i in infos)
