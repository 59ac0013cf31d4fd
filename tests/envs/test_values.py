"""Numbers verified: reward terms, observation slices, action scaling and episode metrics pinned to
the values the env's docstring specifies, on hand-built situations (not only shapes)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from layout_helpers import layout_of

import parcover_env
from parcover_env.config import RewardConfig
from parcover_env.envs.observations import MAX_FIX_AGE
from parcover_env.errors import ActionError
from parcover_env.mission.metrics import EpisodeMetrics, episode_metrics, formation_errors
from parcover_env.mission.rewards import REWARD_KEYS, TERMS, RewardInputs, reward_terms
from parcover_env.sim.act_phase import to_commands

W = RewardConfig(kpoi=10.0, progress=2.0, time=-0.05, collision=-3.0)


# ---------------------------------------------------------------- rewards (pure)
def test_reward_terms_follow_the_weights():
    t = reward_terms(W, TERMS, RewardInputs(1, np.array([1.0, -0.5, 0.0]), np.array([0, 2, 1])))
    assert list(t) == list(TERMS) == ["kpoi", "progress", "time", "collision"]
    np.testing.assert_array_equal(t["kpoi"], [10.0, 10.0, 10.0])  # a KPOI visit pays every agent
    np.testing.assert_array_equal(t["progress"], [2.0, -1.0, 0.0])  # 1 m closer earns progress x 1
    np.testing.assert_array_equal(t["time"], [-0.05, -0.05, -0.05])
    np.testing.assert_array_equal(t["collision"], [0.0, -6.0, -3.0])
    assert REWARD_KEYS == ("reward_kpoi", "reward_progress", "reward_time", "reward_collision")


def test_reward_terms_scale_with_the_count_of_new_kpois():
    t = reward_terms(W, TERMS, RewardInputs(3, np.zeros(2), np.zeros(2, dtype=int)))
    np.testing.assert_array_equal(t["kpoi"], [30.0, 30.0])
    t0 = reward_terms(W, TERMS, RewardInputs(0, np.zeros(2), np.zeros(2, dtype=int)))
    np.testing.assert_array_equal(t0["kpoi"], [0.0, 0.0])
    np.testing.assert_array_equal(t0["collision"], [0.0, 0.0])
    assert t0["collision"].dtype == float


# ---------------------------------------------------------------- rewards (in the env)
def _env(**over):
    overrides = {"observation": {"pose_source": "ground_truth"}, "rewards": {"kpoi": 10.0, "progress": 2.0,
                                                                              "time": -0.05, "collision": -3.0}}
    overrides.update(over)
    return parcover_env.parallel_env("office", preset="ideal", overrides=overrides)


def test_env_progress_reward_is_weight_times_metres_removed():
    env = _env()
    env.reset(seed=0)
    before = env.progress.remaining(env.world.poses()[:, :2])
    _, rew, _, _, infos = env.step({a: np.array([1.0, 0.0], np.float32) for a in env.agents})
    after = env.progress.remaining(env.world.poses()[:, :2])
    for i, a in enumerate(env.possible_agents):
        assert infos[a]["reward_progress"] == pytest.approx(2.0 * (before[i] - after[i]), abs=1e-12)
        assert infos[a]["reward_time"] == -0.05
        assert rew[a] == pytest.approx(sum(infos[a][k] for k in REWARD_KEYS), abs=1e-12)
    assert any(before - after > 0.01)  # driving ahead along the route gets closer


def test_env_kpoi_visit_pays_every_agent():
    env = _env()
    env.reset(seed=0)
    kx, ky = env.scenario.kpois[0]
    env.world.bodies[0].position = (kx, ky)  # put robot 0 on the first KPOI
    _, rew, _, _, infos = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert env.progress.visited[0]
    for a in env.possible_agents:
        assert infos[a]["reward_kpoi"] == 10.0
    _, _, _, _, infos = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert all(infos[a]["reward_kpoi"] == 0.0 for a in env.possible_agents)  # paid once


def test_env_collision_term_counts_new_contacts_of_this_agent():
    env = _env()
    env.reset(seed=0)
    env.world.wall_contacts[1] += 2  # two new wall contacts of robot 1 this step
    _, _, _, _, infos = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert infos["robot_1"]["reward_collision"] == -6.0
    assert infos["robot_0"]["reward_collision"] == 0.0


# ---------------------------------------------------------------- observations
def test_layout_slices_and_bounds():
    lay = layout_of((0.0, -1.0, 10.0, 5.0), 0.5, 1.2, 3, 4.0, 2.5)
    names = ["x", "y", "cos_theta", "sin_theta", "v", "omega", "leader", "slot", "fix_age", "goal_dx",
             "goal_dy", "pred_dx", "pred_dy", "pred_cos", "pred_sin", "pred_visible", "kpois_visited", "time",
             "sonar"]
    assert list(lay.names) == names and lay.size == 21
    for k, n in enumerate(names[:-1]):
        assert lay.slices[n] == slice(k, k + 1)
    assert lay.slices["sonar"] == slice(18, 21)
    diag = math.hypot(10.0, 6.0)
    expect = {"x": (-1.0, 11.0), "y": (-2.0, 6.0), "cos_theta": (-1, 1), "sin_theta": (-1, 1), "v": (-0.5, 0.5),
              "omega": (-1.2, 1.2), "leader": (0, 1), "slot": (0, 1), "fix_age": (0, MAX_FIX_AGE),
              "goal_dx": (-diag - 2, diag + 2), "goal_dy": (-diag - 2, diag + 2), "pred_dx": (-2.5, 2.5),
              "pred_dy": (-2.5, 2.5), "pred_cos": (-1, 1), "pred_sin": (-1, 1), "pred_visible": (0, 1),
              "kpois_visited": (0, 1), "time": (0, 1), "sonar": (0, 4.0)}
    for n, (lo, hi) in expect.items():
        np.testing.assert_allclose(lay.low[lay.slices[n]], lo, rtol=1e-6)
        np.testing.assert_allclose(lay.high[lay.slices[n]], hi, rtol=1e-6)
    assert lay.space().shape == (21,) and lay.low.dtype == np.float32


def test_layout_without_sonar_and_clip_and_get():
    lay = layout_of((0.0, 0.0, 4.0, 3.0), 1.0, 1.0, 0, 4.0, 2.0)
    assert "sonar" not in lay.slices and lay.size == 18
    obs = np.full((2, lay.size), 100.0, np.float32)
    obs[1] = -100.0
    out = lay.clip(obs)
    assert out is obs
    np.testing.assert_array_equal(obs[0], lay.high)
    np.testing.assert_array_equal(obs[1], lay.low)
    assert lay.get(obs, "x").tolist() == [[5.0], [-1.0]]
    assert lay.get(obs[0], "goal_dx").tolist() == [7.0]


def test_env_observation_slices_equal_the_true_quantities():
    env = _env()
    obs, _ = env.reset(seed=0)
    act = {a: np.array([0.8, -0.4], np.float32) for a in env.agents}
    for _ in range(5):
        obs, _, _, _, _ = env.step(act)
    lay, true = env.layout, env.world.poses()
    s = env.scenario
    for i, a in enumerate(env.possible_agents):
        def g(n, o=obs[a]):
            return lay.get(o, n)
        np.testing.assert_allclose(g("x"), true[i, 0], atol=1e-5)
        np.testing.assert_allclose(g("y"), true[i, 1], atol=1e-5)
        np.testing.assert_allclose(g("cos_theta"), math.cos(true[i, 2]), atol=1e-6)
        np.testing.assert_allclose(g("sin_theta"), math.sin(true[i, 2]), atol=1e-6)
        np.testing.assert_allclose(g("v"), 0.8 * s.robot.max_speed, rtol=1e-6)
        np.testing.assert_allclose(g("omega"), -0.4 * s.robot.max_turn_rate, rtol=1e-6)
        assert g("leader")[0] == float(env.team.leader[i])
        assert g("slot")[0] == pytest.approx(env.team.slot[i] / max(env.n_robots - 1, 1))
        assert g("fix_age")[0] == 0.0  # ground-truth poses: always fresh
        goal = env.progress.goals()[i] - true[i, :2]
        c, sn = math.cos(true[i, 2]), math.sin(true[i, 2])
        np.testing.assert_allclose(g("goal_dx"), c * goal[0] + sn * goal[1], atol=1e-5)
        np.testing.assert_allclose(g("goal_dy"), -sn * goal[0] + c * goal[1], atol=1e-5)
        assert g("kpois_visited")[0] == 0.0
        assert g("time")[0] == pytest.approx(5 / s.episode.max_steps)
        p = env.team.predecessor[i]
        if p >= 0 and g("pred_visible")[0] == 1.0:
            d = true[p, :2] - true[i, :2]
            dx, dy = c * d[0] + sn * d[1], -sn * d[0] + c * d[1]
            dist = math.hypot(dx, dy)
            np.testing.assert_allclose(g("pred_dx"), dx, atol=0.05 * dist + 0.02)
            np.testing.assert_allclose(g("pred_dy"), dy, atol=0.05 * dist + 0.02)
            rel = true[p, 2] - true[i, 2]
            np.testing.assert_allclose(g("pred_cos"), math.cos(rel), atol=0.1)
            np.testing.assert_allclose(g("pred_sin"), math.sin(rel), atol=0.1)
    assert any(lay.get(obs[a], "pred_visible")[0] == 1.0 for a in env.possible_agents)


def test_env_kpois_visited_fraction_and_fix_age_cap():
    env = _env()
    env.reset(seed=0)
    kx, ky = env.scenario.kpois[0]
    env.world.bodies[0].position = (kx, ky)
    obs, _, _, _, _ = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    frac = 1 / len(env.scenario.kpois)
    assert env.layout.get(obs["robot_0"], "kpois_visited")[0] == pytest.approx(frac)


# ---------------------------------------------------------------- actions
def test_actions_scale_and_clip():
    out = to_commands({"a": np.array([0.5, -1.0]), "b": np.array([2.0, -3.0])}, ["a", "b"], 0.4, 1.5)
    np.testing.assert_allclose(out, [[0.2, -1.5], [0.4, -1.5]])
    out = to_commands({"a": [1, 0], "b": (0.25, 0.5)}, ["a", "b"], 0.4, 1.5)  # slow, validated path
    np.testing.assert_allclose(out, [[0.4, 0.0], [0.1, 0.75]])
    out = to_commands({"b": np.array([-2.0, 0.1]), "a": np.array([0.0, 1.0])}, ["a", "b"], 2.0, 3.0)
    np.testing.assert_allclose(out, [[0.0, 3.0], [-2.0, 0.3]])  # rows in agent order, not dict order


@pytest.mark.parametrize("actions, match", [
    ([1, 2], "must be a dict"),
    ({"a": np.zeros(2), "b": np.zeros(2), "c": np.zeros(2)}, r"unknown or finished agents \['c'\]"),
    ({"a": np.zeros(2)}, r"missing actions for agents \['b'\]"),
    ({"a": np.zeros(3), "b": np.zeros(2)}, r"a: action must have shape \(2,\)"),
    ({"a": np.zeros(2), "b": np.array([np.nan, 0.0])}, "b: action contains NaN or inf"),
    ({"a": np.zeros(2), "b": np.array([np.inf, 0.0])}, "b: action contains NaN or inf"),
    ({"a": np.array([True, False]), "b": np.zeros(2)}, "a: action is not numeric"),
    ({"a": np.array([1j, 0]), "b": np.zeros(2)}, "a: action is not numeric"),
    ({"a": [[1, 2], [3]], "b": np.zeros(2)}, "a: action is not numeric"),
    ({"a": np.zeros(2, np.float32), "b": np.zeros((2,), np.int64)}, None),
])
def test_action_errors_name_the_agent(actions, match):
    if match is None:
        np.testing.assert_array_equal(to_commands(actions, ["a", "b"], 1.0, 1.0), np.zeros((2, 2)))
        return
    with pytest.raises(ActionError, match=match):
        to_commands(actions, ["a", "b"], 1.0, 1.0)


def test_fast_path_matches_validated_path():
    fast = {"a": np.array([0.3, 5.0]), "b": np.array([-0.7, 0.2])}
    slow = {"a": [0.3, 5.0], "b": [-0.7, 0.2]}
    np.testing.assert_array_equal(to_commands(fast, ["a", "b"], 0.5, 2.0), to_commands(slow, ["a", "b"], 0.5, 2.0))


# ---------------------------------------------------------------- metrics
def test_formation_errors_on_a_hand_built_column():
    # leader at origin heading +x; follower 1 m behind it (camera point 0.1 m ahead of its centre)
    poses = np.array([[0.0, 0.0, 0.0], [-1.1, 0.0, 0.0], [5.0, 5.0, 0.0]])
    pred = np.array([-1, 0, -1])
    dl, dpsi = formation_errors(poses, pred, 0.1, 0.8, math.pi)
    np.testing.assert_allclose(dl, [0.2])  # l = 1.0, l_d = 0.8
    np.testing.assert_allclose(dpsi, [0.0], atol=1e-12)  # psi = pi behind the leader
    poses[1] = [0.0, -1.1, math.pi / 2]  # follower below the leader, heading +y
    dl, dpsi = formation_errors(poses, pred, 0.1, 1.0, math.pi)
    np.testing.assert_allclose(dl, [0.0], atol=1e-12)
    np.testing.assert_allclose(dpsi, [math.pi / 2], atol=1e-12)  # psi = -pi/2: wrap(-pi/2 - pi) = pi/2


def test_compiled_formation_errors_equal_the_numpy_formulas():
    from parcover_env.geometry import atan2, wrap_angle

    g = np.random.default_rng(4)
    poses = np.column_stack([g.uniform(-3, 3, (12, 2)), g.uniform(-4, 4, 12)])
    pred = np.where(g.random(12) < 0.7, g.integers(0, 12, 12), -1)
    f = np.flatnonzero(pred >= 0)
    me, lead = poses[f], poses[pred[f]]
    d = me[:, :2] + 0.12 * np.stack([np.cos(me[:, 2]), np.sin(me[:, 2])], axis=1) - lead[:, :2]
    dl, dpsi = formation_errors(poses, pred, 0.12, 0.5, 2.5)
    assert dl.tobytes() == (np.hypot(d[:, 0], d[:, 1]) - 0.5).tobytes()
    assert dpsi.tobytes() == wrap_angle(atan2(d[:, 1], d[:, 0]) - lead[:, 2] - 2.5).tobytes()
    assert formation_errors(poses, np.full(12, -1), 0.1, 0.5, 0.0)[0].shape == (0,)


def test_episode_metrics_accumulate():
    m = EpisodeMetrics(n_kpois=2, n_robots=2, c_max=10.0, max_speed=0.5, path_lengths=[0.0, 0.0])
    true = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    m.record_step(0.1, 1, true, true + [[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]], wall=2, robot=1)
    m.record_step(0.2, 2, true, true, wall=1, robot=0)
    assert (m.steps, m.time, m.kpois_visited, m.wall_collisions, m.robot_collisions) == (2, 0.2, 2, 3, 1)
    assert m.localization_error == pytest.approx(math.sqrt(25 / 4))  # RMS over robots and steps
    m.add_formation(0.3**2 + 0.4**2, 0.2**2, 2)  # followers' l - l_d (0.3, 0.4), psi - psi_d (0.0, 0.2)
    m.add_formation(0.0, 0.1**2, 1)
    assert m.formation_error_l == pytest.approx(math.sqrt(0.25 / 3))
    assert m.formation_error_psi == pytest.approx(math.sqrt(0.05 / 3))
    m.makespan = 30.0
    s = m.summary()
    assert s["success"] is True and s["collisions"] == 4
    assert s["makespan_ratio"] == pytest.approx(30.0 / (10.0 / 0.5))
    assert not any(k.startswith("_") for k in s)


def test_episode_metrics_failure_and_flat_round_trip():
    m = EpisodeMetrics(n_kpois=3, n_robots=2, c_max=4.0, max_speed=1.0, path_lengths=[1.5, 2.5])
    m.record_step(0.1, 1, np.zeros((2, 3)), np.zeros((2, 3)), wall=0, robot=2)
    m.messages = {"split": 1, "pose": 4}
    s = m.summary()
    assert s["success"] is False and s["makespan_ratio"] is None and s["makespan"] is None
    flat = m.flat()
    assert all(np.ndim(v) == 0 or isinstance(v, np.ndarray) for v in flat.values())
    assert flat["metrics/ended"] == 1.0 and math.isnan(flat["metrics/makespan"]) and flat["metrics/messages"] == 5.0
    back = episode_metrics(flat)
    assert back["success"] is False and back["makespan"] is None and back["kpois_visited"] == 1
    assert back["messages"] == {"split": 1, "promotion": 0, "waypoint": 0, "pose": 4}
    assert back["path_lengths"] == [1.5, 2.5] and back["robot_collisions"] == 2
    for k, v in s.items():
        if k != "messages":
            assert back[k] == v, k
    pre = m.flat(ended=False)
    assert set(pre) == set(flat) and episode_metrics(pre) is None
    assert all(np.all(np.asarray(v) == 0) for v in pre.values())
    assert episode_metrics({}) is None


def test_episode_metrics_zero_c_max_gives_nan_bound():
    m = EpisodeMetrics(n_kpois=1, n_robots=1, c_max=0.0, max_speed=1.0, path_lengths=[0.0])
    m.makespan = 2.0
    assert math.isnan(m.summary()["makespan_ratio"])


def test_layout_goal_bounds_use_the_map_diagonal_off_origin():
    lay = layout_of((2.0, -1.0, 12.0, 5.0), 0.5, 1.2, 0, 4.0, 2.5)
    diag = math.hypot(10.0, 6.0)
    assert lay.high[lay.slices["goal_dx"]][0] == pytest.approx(diag + 2, rel=1e-6)
    assert lay.low[lay.slices["x"]][0] == 1.0 and lay.high[lay.slices["x"]][0] == 13.0


def test_formation_errors_with_the_leader_away_from_the_origin():
    poses = np.array([[3.0, 2.0, 0.0], [1.9, 2.0, 0.0]])  # follower 1.1 m behind, camera point 0.1 m ahead
    dl, dpsi = formation_errors(poses, np.array([-1, 0]), 0.1, 0.5, math.pi)
    np.testing.assert_allclose(dl, [0.5])
    np.testing.assert_allclose(dpsi, [0.0], atol=1e-12)


def test_localization_error_of_a_single_robot_step():
    m = EpisodeMetrics(n_kpois=1, n_robots=1, c_max=0.5, max_speed=0.25, path_lengths=[0.0])
    m.record_step(0.1, 0, np.zeros((1, 3)), np.array([[0.3, 0.4, 0.0]]), wall=0, robot=0)
    assert m.localization_error == pytest.approx(0.5)
    m.makespan = 4.0
    assert m.summary()["makespan_ratio"] == pytest.approx(2.0)  # c_max below 1 m still defines the bound
    back = episode_metrics(m.flat())
    assert type(back["steps"]) is int and type(back["n_kpois"]) is int and type(back["time"]) is float


def test_non_dict_actions_name_their_type():
    with pytest.raises(ActionError, match="got list"):
        to_commands([np.zeros(2)], ["a"], 1.0, 1.0)


def test_unseen_leader_time_counts_leaders_outside_every_footprint_only():
    """``unseen_leader_time`` grows by one control step per leader whose true centre lies outside
    every Kinect footprint; followers out of view and leaders in view add nothing."""
    env = parcover_env.parallel_env("tree")
    env.reset(seed=0)
    dt, system = env.scenario.physics.control_dt, env.kinects
    still = {a: np.zeros(2, np.float32) for a in env.agents}
    leader_xy = [tuple(p) for p in env.true_poses()[env.team.leader, :2]]

    def outside_but_leaders(xy):  # every follower out of view, every leader in view
        return np.array([tuple(p) in leader_xy for p in np.atleast_2d(xy)], dtype=bool)

    system.in_view = outside_but_leaders
    env.step(still)
    leader_xy[:] = [tuple(p) for p in env.true_poses()[env.team.leader, :2]]
    assert env.metrics.unseen_leader_time == 0.0
    system.in_view = lambda xy: np.zeros(len(np.atleast_2d(xy)), dtype=bool)  # nothing in view
    for _ in range(3):
        env.step(still)
    n_leaders = int(env.team.leader.sum())
    assert n_leaders >= 1 and env.metrics.unseen_leader_time == pytest.approx(3 * dt * n_leaders)


def test_env_path_lengths_add_the_distance_each_robot_travels():
    """``metrics.path_lengths`` grows by each robot's straight-line displacement per step (true poses,
    m): driving forward it equals the sum of those steps, and the episode-end info carries it."""
    env = _env()
    env.reset(seed=0)
    before, travelled = env.true_poses()[:, :2], np.zeros(env.n_robots)
    for _ in range(8):
        env.step({a: np.array([1.0, 0.1], dtype=np.float32) for a in env.agents})
        now = env.true_poses()[:, :2]
        travelled += np.hypot(*(now - before).T)
        before = now
    assert env.metrics.path_lengths == pytest.approx(travelled.tolist(), abs=1e-12)
    assert min(env.metrics.path_lengths) > 0.9 * 8 * 0.1 * env.scenario.robot.max_speed  # near full speed ahead
