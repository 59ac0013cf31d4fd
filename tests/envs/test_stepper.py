"""The public stepper's rules: the hand-over's explicit camera view, the slot and metrics rules."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.envs import slots
from parcover_env.mission.team import CameraView, Team, update_team
from parcover_env.sensors.relative import RelativeReading
from parcover_env.sim import outputs_phase, pipeline


class FakeKinects:
    """No fixes, nothing in view (every split falls back on the estimate); records hand-overs."""

    def __init__(self):
        self.last_fixes: dict = {}
        self.handed: list = []

    def in_view(self, xy):
        return np.zeros(len(np.atleast_2d(xy)), dtype=bool)

    def hand_over(self, poses, estimates):
        self.handed.append((poses, estimates))


def _at_first_tp():
    env = parcover_env.parallel_env("tree")
    plan = env.plan
    team = Team(plan, reach_tol=0.2)
    tp = next(t for t in plan.turning_points if tuple(t.robots) == (0, plan.r))
    est = np.zeros((plan.r, 3))
    est[:, :2] = tp.position
    est[:, 0] -= 0.5 * np.arange(plan.r)  # a column along x, facing +x, the leader at the TP
    return team, est, np.zeros(plan.r)


def test_the_hand_over_uses_the_view_it_is_given_and_nothing_else():
    team, est, progress = _at_first_tp()
    kinects = FakeKinects()
    update_team(team, kinects, est, progress, view=None)
    promoted = team.leader.copy()
    promoted[0] = False
    assert promoted.any() and kinects.handed == []  # a split, but no camera view: no hand-over
    team, est, progress = _at_first_tp()
    n = len(est)
    predecessor = np.arange(-1, n - 1)
    reading = RelativeReading(np.tile([0.5, 0.0], (n, 1)), np.zeros(n), predecessor >= 0)
    view = CameraView(predecessor, reading, est.copy())
    update_team(team, kinects, est, progress, view)
    (poses, estimates), = kinects.handed
    assert estimates is view.estimates
    new = np.flatnonzero(team.leader)[1:]
    assert sorted(poses) == new.tolist()
    for i in new:  # the robot ahead (its estimate), 0.5 m behind it as the camera saw
        np.testing.assert_allclose(poses[i], est[i - 1] - [0.5, 0.0, 0.0], atol=1e-12)


def test_slot_info_rules():
    env = parcover_env.parallel_env("office", overrides={"episode": {"max_steps": 2}})
    env.reset(seed=0)
    still = {a: np.zeros(2, np.float32) for a in env.agents}
    _, _, term, trunc, infos = env.step(still)
    info = slots.slot_info(dict(infos["robot_0"]), np.ones(3), False, False)
    assert info["active"] and "metrics" not in info and "terminal_observation" not in info
    _, _, term, trunc, infos = env.step(still)
    assert trunc["robot_0"] and not term["robot_0"]
    info = slots.slot_info(dict(infos["robot_0"]), np.ones(3), False, True)
    assert info["TimeLimit.truncated"] is True and info["terminal_observation"].tolist() == [1.0] * 3
    assert info["metrics"]["steps"] == 2 and "ended" not in info["metrics"]
    done = slots.slot_info(dict(infos["robot_0"]), np.ones(3), True, True)
    assert done["TimeLimit.truncated"] is False  # terminated wins
    gone = slots.slot_info({}, np.zeros(3), False, False, ended=True)  # left before its team
    assert gone["TimeLimit.truncated"] is False and "terminal_observation" in gone


def test_one_world_step_is_the_env_step():
    a, b = parcover_env.parallel_env("office"), parcover_env.parallel_env("office")
    oa, _ = a.reset(seed=3)
    ob, _ = b.reset(seed=3)
    acts = {n: np.array([0.5, 0.2], np.float32) for n in a.agents}
    obs, out = pipeline.step([b], [acts])
    rew, term, trunc, infos = outputs_phase.agent_dicts(b.possible_agents, out)
    ra = a.step(acts)
    assert all(np.array_equal(ra[0][n], obs[0][i]) for i, n in enumerate(a.possible_agents))
    assert ra[1] == rew and ra[2] == term and ra[3] == trunc
    view = b.camera_view  # the predecessors it was measured against: a copy of the team's (shared) rows
    assert np.array_equal(view.predecessor, b.team.predecessor)
    assert not np.shares_memory(view.predecessor, b.team.predecessor)
    assert b.camera_views.predecessor.shape == (1, b.n_robots) and b.camera_index == 0
    with pytest.raises(RuntimeError, match="finished episode"):
        b.agents = []
        pipeline.step([b], [acts])


def test_step_by_agent_slot_is_each_worlds_agent_dicts_and_clears_an_ended_world():
    import copy

    worlds = []
    for seed in (0, 1):
        w = parcover_env.parallel_env("office", overrides={"episode": {"max_steps": 3}})
        w.reset(seed=seed)
        worlds.append(w)
    worlds[1].steps = 2  # by hand: world 1 reaches its step limit at the next step, world 0 does not
    twins = copy.deepcopy(worlds)
    n = worlds[0].n_robots
    rng = np.random.default_rng(4)
    acts = rng.uniform(-1, 1, (2, n, 2)).astype(np.float32)
    obs, out = pipeline.step(worlds, acts, active=True)
    obs_ref, ref = pipeline.step(twins, [dict(zip(w.agents, a, strict=True)) for w, a in zip(twins, acts, strict=True)],
                                active=True)  # the same actions as one dict per world
    assert np.array_equal(obs, obs_ref)
    assert out.terminated == [False, False] and out.truncated == [False, True]
    assert [w.agents for w in worlds] == [worlds[0].possible_agents, []]
    for k in range(2):
        rewards, term, trunc, infos = outputs_phase.agent_dicts(twins[k].possible_agents, ref, k)
        assert list(rewards) == list(infos) == twins[k].possible_agents
        assert out.rewards[k].tolist() == list(rewards.values())
        assert list(term.values()) == [out.terminated[k]] * n and list(trunc.values()) == [out.truncated[k]] * n
        slots = out.infos[k * n:(k + 1) * n]
        for got, want in zip(slots, infos.values(), strict=True):
            assert list(got) == list(want) and got["active"] is True
            assert all(np.array_equal(got[x], want[x], equal_nan=True) for x in want)
            assert got["metrics/ended"] == float(k == 1) and got["metrics/steps"] == float(k == 1)  # one step recorded
        assert out.rewards[k].tolist() == [sum(info[f"reward_{t}"] for t in worlds[k].terms) for info in slots]
    assert len({id(i) for i in out.infos}) == 2 * n  # one dict per slot
