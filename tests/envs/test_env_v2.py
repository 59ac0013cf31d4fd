"""Env version 2 (issue 28 items 3, 4): every new observation entry and reward term pinned by value on
hand-built situations; the token state has one shape on every map and round-trips; v1 is unchanged."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import parcover_env
from parcover_env import parcover_v2
from parcover_env.config import RewardConfig
from parcover_env.envs import ParallelCoverageEnv, critic_state
from parcover_env.envs.obs_spec import ENTRIES, V2_ENTRIES
from parcover_env.envs.obs_v2 import RouteFacts, TeamRows, fill, group_sizes, route_facts, target_kpois, team_rows
from parcover_env.errors import ConfigError
from parcover_env.mission.rewards import TERMS, TERMS_V2, RewardInputs, own_visits, paid_terms, reward_terms

NAMES = [e.name for e in ENTRIES if e.name in V2_ENTRIES]
K = 4


def _slices(k: int = K) -> dict[str, slice]:
    sizes = {"wp_dx": 3, "wp_dy": 3, **{n: k for n in NAMES if n.startswith("mate_")}}
    out, at = {}, 0
    for n in NAMES:
        out[n] = slice(at, at + sizes.get(n, 1))
        at += sizes.get(n, 1)
    return out


def _facts() -> RouteFacts:
    """Three robots; robot 0 owns KPOI 0 at (0, 1), robot 1 KPOIs 1 then 2, robot 2 none.
    Robot 0's route (1,1) (1,2) (2,2) (3,2); its TPs at plan distance 1 (at (1, 2)) and 3 (at (0, 4))."""
    pts = np.array([[[1, 1], [1, 2], [2, 2], [3, 2]], [[0, 0], [5, 5], [5, 5], [5, 5]],
                    [[0, 0], [6, 0], [6, 0], [6, 0]]], dtype=float)
    tp_counts = np.array([[[3, 2, 2], [2, 2, 1]], [[3, 2, 1], [0, 0, 0]], [[3, 2, 2], [0, 0, 0]]], dtype=float)
    return RouteFacts(own=np.array([[0, -1], [1, 2], [-1, -1]]), end=pts[:, -1], pts=pts,
                      length=np.array([4, 2, 2]), kpois=np.array([[0.0, 1.0], [4.0, 4.0], [5.0, 6.0]]),
                      tp_dist=np.array([[1.0, 3.0], [1.0, np.inf], [1.0, np.inf]]),
                      tp_xy=np.array([[[1, 2], [0, 4]], [[1, 2], [0, 0]], [[1, 2], [0, 0]]], dtype=float),
                      tp_counts=tp_counts)


def _rows(visited=(False, False, False), progress=(1.5, 0.0, 5.0)) -> TeamRows:
    """Robot 0 at (1, 1) heading +y at 0.5 m/s, leader; robot 1 at (1, 2) heading +x at 0.2 m/s;
    robot 2 at (3, 1) heading -x, standing, leader."""
    est = np.array([[1.0, 1.0, math.pi / 2], [1.0, 2.0, 0.0], [3.0, 1.0, math.pi]])
    vel = np.array([[0.5, 0.0], [0.2, 0.0], [0.0, 0.0]])
    return TeamRows(est[None], vel[None], np.array([[True, False, True]]), np.array([[2.0, 2.0, 1.0]]),
                    np.array([[2, 1, 1]]), np.array([progress]), np.array([visited]))


def _observe(rows: TeamRows, k: int = K) -> dict[str, np.ndarray]:
    sl = _slices(k)
    obs = np.full((rows.est.shape[0], 3, max(s.stop for s in sl.values())), np.nan)
    fill(obs, sl, _facts(), rows, k)
    return {n: obs[0, :, s] for n, s in sl.items()}


def test_own_kpoi_bearing_and_distance_in_the_robot_frame():
    o = _observe(_rows())
    # robot 0 faces +y; its KPOI at (0, 1) lies 1 m to its left
    assert o["own_kpoi_cos"][0, 0] == pytest.approx(0.0, abs=1e-12)
    assert o["own_kpoi_sin"][0, 0] == pytest.approx(1.0)
    assert o["own_kpoi_dist"][0, 0] == pytest.approx(1.0)
    # robot 1 at (1, 2) facing +x: its first KPOI (4, 4) is 3 ahead, 2 left
    assert o["own_kpoi_dist"][1, 0] == pytest.approx(math.hypot(3, 2))
    assert (o["own_kpoi_cos"][1, 0], o["own_kpoi_sin"][1, 0]) == pytest.approx((3 / math.hypot(3, 2),
                                                                                2 / math.hypot(3, 2)))
    # robot 2 owns no KPOI: its target is its route's end (6, 0), and its work counts as done
    assert o["own_kpoi_dist"][2, 0] == pytest.approx(math.hypot(3, 1))
    np.testing.assert_array_equal(o["done_mask"][:, 0], [0.0, 0.0, 1.0])


def test_target_moves_to_the_next_own_kpoi_and_done_mask_follows_the_visits():
    facts = _facts()
    xy, done = target_kpois(facts, np.array([[False, True, False]]))
    np.testing.assert_array_equal(xy[0, 1], [5.0, 6.0])  # KPOI 1 visited: robot 1 heads for KPOI 2
    np.testing.assert_array_equal(done[0], [False, False, True])
    xy, done = target_kpois(facts, np.array([[True, True, True]]))
    np.testing.assert_array_equal(xy[0, 1], [5.0, 6.0])  # all visited: the last one
    np.testing.assert_array_equal(done[0], [True, True, True])
    o = _observe(_rows(visited=(True, False, False)))
    np.testing.assert_array_equal(o["done_mask"][:, 0], [1.0, 0.0, 1.0])


def test_route_preview_is_the_next_vertices_in_the_robot_frame_repeating_the_end():
    o = _observe(_rows())
    # robot 0 (waypoint 2): (2, 2), (3, 2), (3, 2) seen from (1, 1) facing +y: x = dy, y = -dx
    np.testing.assert_allclose(o["wp_dx"][0], [1.0, 1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(o["wp_dy"][0], [-1.0, -2.0, -2.0], atol=1e-12)
    # robot 1 (waypoint 1 of 2 vertices): (5, 5) three times, from (1, 2) facing +x
    np.testing.assert_allclose(o["wp_dx"][1], [4.0] * 3, atol=1e-12)
    np.testing.assert_allclose(o["wp_dy"][1], [3.0] * 3, atol=1e-12)


def test_next_tp_is_the_first_ahead_of_the_plan_progress_with_its_counts():
    o = _observe(_rows(progress=(1.5, 0.5, 5.0)))
    # robot 0 passed the TP at 1 m: the next is at 3 m, (0, 4): 3 m ahead of it, 1 m to its left
    assert o["tp_ahead"][0, 0] == 1.0
    assert (o["tp_dx"][0, 0], o["tp_dy"][0, 0]) == pytest.approx((3.0, 1.0), abs=1e-12)
    assert (o["tp_group"][0, 0], o["tp_branches"][0, 0], o["tp_own_branch"][0, 0]) == (2.0, 2.0, 1.0)
    # robot 1 before its only TP (1, 2): on top of it, counts of the first TP
    assert (o["tp_ahead"][1, 0], o["tp_group"][1, 0], o["tp_own_branch"][1, 0]) == (1.0, 3.0, 1.0)
    # robot 2 past every TP: zeros
    names = ("tp_ahead", "tp_dx", "tp_dy", "tp_group", "tp_branches", "tp_own_branch")
    assert [o[n][2, 0] for n in names] == [0] * 6
    np.testing.assert_array_equal(o["group_size"][:, 0], [2.0, 2.0, 1.0])


def test_nearest_teammates_are_ordered_by_distance_padded_with_zeros_and_mask_0():
    o = _observe(_rows())
    # robot 0 at (1, 1) facing +y: robot 1 (1 m, straight ahead) then robot 2 (2 m, to its right)
    np.testing.assert_allclose(o["mate_dx"][0], [1.0, 0.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(o["mate_dy"][0], [0.0, -2.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(o["mate_mask"][0], [1.0, 1.0, 0.0, 0.0])
    np.testing.assert_array_equal(o["mate_leader"][0], [0.0, 1.0, 0.0, 0.0])
    # relative headings: robot 1 faces +x (-90 deg from robot 0), robot 2 faces -x (+90 deg)
    np.testing.assert_allclose(o["mate_cos"][0], [0.0, 0.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(o["mate_sin"][0], [-1.0, 1.0, 0.0, 0.0], atol=1e-12)
    # velocities: robot 1 (0.2, 0) - robot 0 (0, 0.5) = (0.2, -0.5) world = (-0.5, -0.2) in robot 0's frame;
    # robot 2 (standing) - robot 0 = (0, -0.5) world = (-0.5, 0)
    np.testing.assert_allclose(o["mate_dvx"][0], [-0.5, -0.5, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(o["mate_dvy"][0], [-0.2, 0.0, 0.0, 0.0], atol=1e-12)
    # robot 1 (0.2 m/s along +x, its heading): robot 0 (0, 0.5) - (0.2, 0), robot 2 (0, 0) - (0.2, 0)
    np.testing.assert_allclose(o["mate_dvx"][1], [-0.2, -0.2, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(o["mate_dvy"][1], [0.5, 0.0, 0.0, 0.0], atol=1e-12)
    # robot 2 at (3, 1) facing -x: robot 0 is 2 m ahead, robot 1 sqrt(5) m (2 ahead, 1 right)
    np.testing.assert_allclose(o["mate_dx"][2], [2.0, 2.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(o["mate_dy"][2], [0.0, -1.0, 0.0, 0.0], atol=1e-12)
    o1 = _observe(_rows(), k=1)  # k = 1: only the nearest
    assert o1["mate_dx"].shape == (3, 1) and o1["mate_dx"][0, 0] == pytest.approx(1.0)
    assert o1["mate_dy"][2, 0] == pytest.approx(0.0, abs=1e-12) and o1["mate_mask"][:, 0].tolist() == [1, 1, 1]


def test_worlds_stacked_give_the_same_bits_as_one_world():
    one = _rows()
    two = TeamRows(*[np.concatenate([a, a * 1.0 if a.dtype.kind == "f" else a]) for a in one])
    sl = _slices()
    d = max(s.stop for s in sl.values())
    a, b = np.zeros((1, 3, d)), np.zeros((2, 3, d))
    fill(a, sl, _facts(), one, K)
    fill(b, sl, _facts(), two, K)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[0], b[1])


def test_route_facts_of_a_plan():
    env = parcover_v2.parallel_env("office", preset="ideal")
    f = env.route_facts
    np.testing.assert_array_equal(f.own[:, 0], [r.kpois[0] for r in env.plan.robots])
    tp = env.plan.turning_points[0]
    assert f.tp_dist[0, 0] == tp.distance and tuple(f.tp_xy[0, 0]) == tp.position
    np.testing.assert_array_equal(f.tp_counts[:, 0], [[2, 2, 1], [2, 2, 1]])  # 2 arrive, 2 branches of 1
    g = route_facts(env.plan, f.pts, f.length, f.kpois)
    assert all(np.array_equal(x, y) for x, y in zip(f, g, strict=True))


# ---------------------------------------------------------------- rewards
def test_own_visits_pay_only_the_owner_who_visits():
    newly = np.array([True, True, True, False])
    visitor = np.array([0, 0, 2, 1])
    owner = np.array([0, 1, 2, 1])
    np.testing.assert_array_equal(own_visits(newly, visitor, owner, 3), [1.0, 0.0, 1.0])  # KPOI 1 is robot 1's
    w = RewardConfig(kpoi=1.0, own_kpoi=10.0)
    own = own_visits(newly, visitor, owner, 3)
    t = reward_terms(w, paid_terms(TERMS_V2, RewardConfig()), RewardInputs(3, np.zeros(3), np.zeros(3, int), own))
    assert list(t) == list(TERMS_V2) == ["own_kpoi", *TERMS]
    np.testing.assert_array_equal(t["own_kpoi"], [10.0, 0.0, 10.0])
    np.testing.assert_array_equal(t["kpoi"], [3.0, 3.0, 3.0])
    v1 = reward_terms(w, paid_terms(TERMS, RewardConfig()), RewardInputs(3, np.zeros(3), np.zeros(3, int)))
    assert list(v1) == list(TERMS)


def _v2_env():
    return parcover_v2.parallel_env("office", preset="ideal", overrides={"observation": {"pose_source":
                                                                                          "ground_truth"}})


def _stand(env):
    return {a: np.zeros(2, np.float32) for a in env.agents}


def test_env_own_kpoi_goes_to_the_visitor_only_and_the_team_bonus_to_all():
    env = _v2_env()
    env.reset(seed=0)
    own0 = env.plan.robots[0].kpois[0]
    env.world.bodies[0].position = tuple(env.scenario.kpois[own0])  # robot 0 on its own KPOI
    obs, rew, _, _, infos = env.step(_stand(env))
    assert [infos[a]["reward_own_kpoi"] for a in env.possible_agents] == [10.0, 0.0]
    assert [infos[a]["reward_kpoi"] for a in env.possible_agents] == [1.0, 1.0]
    for a in env.possible_agents:
        assert rew[a] == pytest.approx(sum(infos[a][f"reward_{t}"] for t in TERMS_V2), abs=1e-12)
    assert [infos[a]["route_done"] for a in env.possible_agents] == [1.0, 0.0]
    assert [env.layout.get(obs[a], "done_mask")[0] for a in env.possible_agents] == [1.0, 0.0]
    _, _, _, _, infos = env.step(_stand(env))
    assert infos["robot_0"]["reward_own_kpoi"] == 0.0  # paid once


def test_env_visiting_a_teammates_kpoi_pays_only_the_team_bonus():
    env = _v2_env()
    env.reset(seed=0)
    other = env.plan.robots[1].kpois[0]
    env.world.bodies[0].position = tuple(env.scenario.kpois[other])  # robot 0 on robot 1's KPOI
    _, _, _, _, infos = env.step(_stand(env))
    assert [infos[a]["reward_own_kpoi"] for a in env.possible_agents] == [0.0, 0.0]
    assert [infos[a]["reward_kpoi"] for a in env.possible_agents] == [1.0, 1.0]
    assert [infos[a]["route_done"] for a in env.possible_agents] == [0.0, 1.0]  # robot 1's work is done


def test_env_reads_the_bearing_and_distance_of_a_robot_placed_by_hand():
    env = _v2_env()
    env.reset(seed=0)
    kx, ky = env.scenario.kpois[env.plan.robots[1].kpois[0]]
    body = env.world.bodies[1]
    body.position, body.angle = (kx - 0.6, ky - 0.8), math.pi / 2  # KPOI 1 m away: 0.8 ahead, 0.6 right
    obs, *_ = env.step(_stand(env))
    o = obs["robot_1"]
    assert env.layout.get(o, "own_kpoi_dist")[0] == pytest.approx(1.0, abs=1e-6)
    assert env.layout.get(o, "own_kpoi_cos")[0] == pytest.approx(0.8, abs=1e-6)
    assert env.layout.get(o, "own_kpoi_sin")[0] == pytest.approx(-0.6, abs=1e-6)


def test_v2_settings_and_v1_unchanged():
    env = _v2_env()
    assert env.scenario.rewards.own_kpoi == 10.0 and env.scenario.rewards.kpoi == 1.0
    assert env.metadata["name"] == "parcover_v2" and env.terms == TERMS_V2
    v1 = parcover_env.parallel_env("office", preset="ideal")
    assert v1.terms == TERMS and v1.scenario.rewards.own_kpoi == 0.0
    assert not set(V2_ENTRIES) & set(v1.layout.names)
    _, infos = v1.reset(seed=0)
    assert "route_done" not in infos["robot_0"] and "reward_own_kpoi" not in infos["robot_0"]
    assert v1.state().shape == (5 * 2 + 2 + 1,)
    assert set(V2_ENTRIES) <= set(env.layout.names)
    custom = parcover_v2.parallel_env("office", overrides={"rewards": {"kpoi": 2.0}, "observation": {"neighbours": 2}})
    assert custom.scenario.rewards.kpoi == 2.0 and custom.layout.slices["mate_dx"].stop - \
        custom.layout.slices["mate_dx"].start == 2


# ---------------------------------------------------------------- state
@pytest.mark.parametrize("scenario", ["office", "tree", "hallway", "generated:7"])
def test_state_has_one_shape_on_every_map_and_round_trips(scenario):
    env = parcover_v2.parallel_env(scenario)
    env.reset(seed=1)
    env.step({a: np.array([0.5, 0.1], np.float32) for a in env.agents})
    st = env.state()
    assert st.shape == env.state_space.shape == (critic_state.STATE_SIZE,) == (322,)
    assert env.state_space.contains(st)
    tok = critic_state.state_tokens(st)
    assert tok.robots.shape == (16, 11) and tok.kpois.shape == (32, 3) and tok.globals.shape == (2,)
    assert tok.robot_mask.sum() == env.n_robots and tok.kpoi_mask.sum() == len(env.scenario.kpois)
    assert not tok.robots[~tok.robot_mask].any() and not tok.kpois[~tok.kpoi_mask].any()  # zero padding
    true = env.true_poses()
    np.testing.assert_allclose(tok.robots[:env.n_robots, :2], true[:, :2], atol=1e-5)
    np.testing.assert_allclose(tok.robots[:env.n_robots, 6:8], env.estimate[:, :2] - true[:, :2], atol=1e-5)
    np.testing.assert_array_equal(critic_state.flat_state(tok), st)
    batch = np.stack([st, st * 0])
    assert np.array_equal(critic_state.flat_state(critic_state.state_tokens(batch)), batch)


def test_state_tokens_hold_velocity_role_progress_done_and_kpois():
    env = _v2_env()
    env.reset(seed=0)
    before = env.true_poses()
    own0 = env.plan.robots[0].kpois[0]
    env.step({"robot_0": np.array([1.0, 0.0], np.float32), "robot_1": np.zeros(2, np.float32)})
    tok = critic_state.state_tokens(env.state())
    after = env.true_poses()
    v = (after[0, :2] - before[0, :2]) / env.scenario.physics.control_dt
    np.testing.assert_allclose(tok.robots[0, 4:6], v, atol=1e-5)
    assert 0.5 * env.scenario.robot.max_speed < np.hypot(*v) <= env.scenario.robot.max_speed + 1e-9
    np.testing.assert_array_equal(tok.robots[:2, 8], env.team.leader.astype(float))
    assert 0 < tok.robots[0, 9] < 1 and tok.robots[1, 9] == 0  # robot 0 made progress, robot 1 did not
    np.testing.assert_allclose(tok.kpois[:2, :2], env.scenario.kpois, atol=1e-6)
    env.world.bodies[0].position = tuple(env.scenario.kpois[own0])
    env.step(_stand(env))
    tok = critic_state.state_tokens(env.state())
    assert tok.robots[0, 10] == 1.0 and tok.robots[1, 10] == 0.0  # done flags
    assert tok.kpois[own0, 2] == 1.0 and tok.kpois[1 - own0, 2] == 0.0
    assert tok.globals[1] == 0.5 and tok.globals[0] == pytest.approx(2 / env.scenario.episode.max_steps)


def test_too_many_robots_or_kpois_raise_one_clear_error():
    s = parcover_env.load_scenario("office")
    with pytest.raises(ConfigError, match="n_robots: observation version 2 takes at most 16 robots"):
        critic_state.check_maxima(s, 17)
    many = dataclasses.replace(s, kpois=tuple((0.1 * i, 1.0) for i in range(33)))
    with pytest.raises(ConfigError, match="kpois: .* at most 32 KPOIs"):
        critic_state.check_maxima(many, 2)
    critic_state.check_maxima(s, 16)


def test_the_state_table_in_the_docstring_is_generated():
    assert critic_state.markdown_table().replace("\n", "\n    ") in ParallelCoverageEnv.__doc__
    assert "STATE_TABLE" not in ParallelCoverageEnv.__doc__
    size = 16 * len(critic_state.ROBOT_FEATURES) + 32 * len(critic_state.KPOI_FEATURES) + 2
    assert size == critic_state.STATE_SIZE


def test_v2_passes_the_pettingzoo_api_tests_with_constant_info_keys():
    from pettingzoo.test import api_test, parallel_api_test

    parallel_api_test(parcover_v2.parallel_env("office"), num_cycles=100)
    api_test(parcover_v2.env("office"), num_cycles=20)
    env = parcover_v2.parallel_env("office")
    _, infos = env.reset(seed=0)
    keys = list(infos["robot_0"])
    _, _, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
    assert list(infos["robot_0"]) == keys and "route_done" in keys and "reward_own_kpoi" in keys


def test_bad_v2_settings_raise_one_clear_error_at_construction():
    with pytest.raises(ConfigError, match="generated:7: n_robots: observation version 2 takes at most 16"):
        parcover_v2.parallel_env("generated:7", overrides={"n_robots": 17})
    with pytest.raises(ConfigError, match="observation.neighbours: must be an integer in"):
        parcover_v2.parallel_env("office", overrides={"observation": {"neighbours": 16}})
    with pytest.raises(ConfigError, match="observation.version"):
        parcover_env.parallel_env("office", overrides={"observation": {"version": 3}})


def test_group_sizes_from_the_leader_flags_by_value_and_as_the_teams_groups():
    leader = np.array([[True, False, False, True, False], [True, True, True, True, True]])
    assert group_sizes(leader).tolist() == [[3.0, 3.0, 3.0, 2.0, 2.0], [1.0] * 5]
    assert group_sizes(leader[:1]).dtype == np.float64
    envs = [ParallelCoverageEnv("tree", overrides={"observation": {"version": 2}}) for _ in range(2)]
    for e in envs:
        e.reset(seed=0)
    team = envs[1].team
    tp = next(t for t in envs[1].plan.turning_points if tuple(t.robots) == (0, team.n))
    est = np.zeros((team.n, 2))
    est[0] = tp.position
    assert team.update(est, np.zeros(team.n)) and len(team.groups) > 1  # world 1 split, world 0 did not
    want = team_rows(envs).group_size
    assert want[0].tolist() == [float(team.n)] * team.n and want[1].tolist() != want[0].tolist()
    np.testing.assert_array_equal(group_sizes(np.stack([e.team.leader for e in envs])), want)
