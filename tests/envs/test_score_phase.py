"""The (K, N) block functions of the score, observe and outputs phases: K = 2 worlds in different
states give what two K = 1 calls give, bit for bit, and pinned values on hand-built cases."""

from __future__ import annotations

import copy
import math
from collections import Counter
from types import SimpleNamespace

import numpy as np
import pytest
from layout_helpers import layout_of

import parcover_env
from parcover_env.envs.obs_v2 import target_kpois
from parcover_env.envs.observations import ScalarInputs
from parcover_env.mission import kernels as step_kernels
from parcover_env.mission import rewards
from parcover_env.mission.metrics import (
    EpisodeMetrics,
    formation_errors,
    formation_errors_many,
    record_step,
    record_steps,
)
from parcover_env.mission.rewards import TERMS, TERMS_V2, RewardInputs, own_visits, reward_terms
from parcover_env.mission.team import CameraView, Team, count_waypoints_many, update_team, update_teams
from parcover_env.scenarios.progress import RouteTracker, goals_many, step_many, update_many
from parcover_env.sensors.relative import RelativeReading
from parcover_env.sim import act_phase, outputs_phase, pipeline, score_phase

ROUTE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.5], [2.0, 0.0], [4.0, 0.0]])
KPOIS = np.array([[2.0, 1.5], [4.0, 0.0]])


def _tracker():
    return RouteTracker(KPOIS, 0.2, [ROUTE, ROUTE + [0.0, 0.1]], waypoint_tol=0.15, lookahead=0.4)


def _state(t):
    return [t.visited.copy(), t.visit_time.copy(), t.visitor.copy(), t.progress.copy(), t.waypoint.copy(),
            t.advanced.copy()]


def _same(a, b):
    return all(np.array_equal(x, y, equal_nan=x.dtype.kind == "f") and x.dtype == y.dtype for x, y in zip(a, b))


# ---------------------------------------------------------------- route progress
def test_update_many_is_each_tracker_alone_and_visits_by_value():
    walk = [np.array([[x, 0.05], [x - 0.3, 0.1]]) for x in np.arange(0.0, 2.05, 0.25)]
    a, b = _tracker(), _tracker()
    for xy in walk:  # world a walks to the foot of the spur, world b stays behind
        a.update(xy, xy, 1.0)
    a1, b1 = copy.deepcopy(a), copy.deepcopy(b)
    true = np.array([[[2.0, 1.45], [0.5, 0.1]], [[0.4, 0.0], [0.2, 0.1]]])  # a's robot 0 reaches KPOI 0
    est = true + 0.01
    n_new, goal, rem = step_many([a, b], true, est, [3.0, 4.0])
    assert n_new.tolist() == [1, 0]
    assert a1.update(true[0], est[0], 3.0) == 1 and b1.update(true[1], est[1], 4.0) == 0
    assert _same(_state(a), _state(a1)) and _same(_state(b), _state(b1))
    assert a.visited.tolist() == [True, False] and a.visit_time[0] == 3.0 and a.visitor.tolist() == [0, -1]
    assert np.array_equal(goal, np.stack([a1.goals(), b1.goals()])) and np.array_equal(goal, goals_many([a, b])[0])
    assert np.array_equal(rem, np.stack([a1.remaining(true[0]), b1.remaining(true[1])]))
    assert update_many([a], true[:1], est[:1], [5.0]).tolist() == [0] and a.visit_time[0] == 3.0
    # robot 0 of b at (0.4, 0): goal 0.4 m ahead on the route, at (0.8, 0); route length 2 + 1.5 * 2 + 2 = 7 m
    assert rem[1, 0] == pytest.approx(0.4 + (7.0 - 0.8))


# ---------------------------------------------------------------- team
class RecordingKinects:
    """Kinects with the given fixes; nothing in view; records whether the team logic asked."""

    def __init__(self, fixes=None):
        self.last_fixes = fixes or {}
        self.asked = 0
        self.handed = []

    def in_view(self, xy):
        self.asked += 1
        return np.zeros(len(np.atleast_2d(xy)), dtype=bool)

    def hand_over(self, poses, estimates):
        self.handed.append(poses)


def _office_team():
    env = parcover_env.parallel_env("office")
    return Team(env.plan, reach_tol=0.2), env.plan.turning_points[0]


def test_team_tp_ahead_lists_the_leaders_pending_tp():
    team, tp = _office_team()
    assert team.tp_ahead[0].tolist() == [*tp.position, tp.distance] and np.isnan(team.tp_ahead[1]).all()
    team.update(np.array([tp.position, tp.position]), np.array([tp.distance, 0.0]))
    assert np.isnan(team.tp_ahead).all()  # split: no TP ahead of either robot
    assert np.isnan(Team(parcover_env.parallel_env("office").plan, "individual").tp_ahead).all()


def test_update_teams_splits_exactly_the_worlds_update_team_splits():
    (t_far, tp), (t_at, _), (t_fix, _) = _office_team(), _office_team(), _office_team()
    far = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    at = np.array([[*tp.position, 0.0], [*tp.position, 0.0]])
    est = np.stack([far, at, far])
    progress = np.zeros((3, 2))
    kin = [RecordingKinects(), RecordingKinects(), RecordingKinects({0: np.array([*tp.position, 0.0])})]
    ref = [copy.deepcopy(t) for t in (t_far, t_at, t_fix)]
    ref_kin = copy.deepcopy(kin)
    reading = RelativeReading(np.array([[0.0, 0.0], [0.5, 0.0]]), np.zeros(2), np.array([False, True]))
    views = [CameraView(np.array([-1, 0]), reading, e.copy()) for e in est]
    assert update_teams([t_far, t_at, t_fix], kin, est, progress, views.__getitem__) == [1, 2]  # the worlds run
    for team, k, e, v in zip(ref, ref_kin, est, views, strict=True):
        update_team(team, k, e, np.zeros(2), v)
    assert [t.groups for t in (t_far, t_at, t_fix)] == [t.groups for t in ref] == [[(0, 2)], [(0, 1), (1, 2)],
                                                                                   [(0, 1), (1, 2)]]
    assert t_fix.splits == {"kinect": 1} and t_at.splits == {"odometry": 1}
    assert kin[0].asked == 0  # far from its TP, no fix: the world was not even looked at
    # the promoted robot 1 is handed over 0.5 m behind its leader, where its camera view puts it
    assert [len(k.handed) for k in kin] == [len(k.handed) for k in ref_kin] == [0, 1, 1]
    assert kin[1].handed[0].keys() == {1} and kin[1].handed[0][1][0] == pytest.approx(tp.position[0] - 0.5)


def _may_split(*args) -> np.ndarray:
    out = np.ones(len(args[0]), dtype=bool)  # every entry is written
    step_kernels.may_split(*args, out)
    return out


def test_may_split_by_distance_estimate_and_fix():
    tp = np.array([[[1.0, 0.0, 5.0], [np.nan] * 3]])
    est = np.zeros((1, 2, 3))
    no_fix = np.full((1, 2, 2), np.nan)
    assert _may_split(tp, est, np.array([[4.9, 0.0]]), no_fix, 0.2, 0.0).tolist() == [False]
    assert _may_split(tp, est, np.array([[5.0 - 1e-6, 0.0]]), no_fix, 0.2, 0.0).tolist() == [True]
    assert _may_split(tp, est, np.zeros((1, 2)), no_fix, 1.0, 0.0).tolist() == [True]  # 1 m off
    assert _may_split(tp, est, np.zeros((1, 2)), no_fix, 0.999, 0.0).tolist() == [False]
    fix = no_fix.copy()
    fix[0, 0] = [1.1, 0.0]
    assert _may_split(tp, est, np.zeros((1, 2)), fix, 0.2, 0.0).tolist() == [True]
    fix[0, 0] = [np.nan, np.nan]
    fix[0, 1] = [1.0, 0.0]  # a fix of a robot heading for no TP
    assert _may_split(tp, est, np.zeros((1, 2)), fix, 0.2, 0.0).tolist() == [False]


def test_count_waypoints_many_counts_leaders_only():
    teams = [SimpleNamespace(messages=Counter()), SimpleNamespace(messages=Counter({"waypoint": 2}))]
    advanced = np.array([[True, True, False], [False, True, True]])
    leader = np.array([[True, False, False], [True, True, True]])
    count_waypoints_many(teams, advanced, leader)
    assert [t.messages["waypoint"] for t in teams] == [1, 4]
    assert "waypoint" in teams[0].messages  # counted even when 0, as Team.count_waypoints does
    count_waypoints_many(teams, advanced & False, leader)
    assert [dict(t.messages) for t in teams] == [{"waypoint": 1}, {"waypoint": 4}]


# ---------------------------------------------------------------- rewards
def test_reward_terms_and_own_visits_of_two_worlds_are_each_world_alone():
    w = SimpleNamespace(kpoi=10.0, own_kpoi=5.0, progress=2.0, time=-0.01, collision=-1.0)
    newly = np.array([[True, True, False], [False, True, True]])
    visitor = np.array([[1, 2, -1], [0, 0, 2]])
    owner = np.array([1, 0, 2])
    own = own_visits(newly, visitor, owner, 3)
    assert own.tolist() == [[0.0, 1.0, 0.0], [1.0, 0.0, 1.0]]  # robot 2 of world 0 visited robot 0's
    progress = np.array([[0.5, -0.25, 0.0], [1.0, 0.0, 0.125]])
    contacts = np.array([[0, 1, 2], [3, 0, 0]])
    block = reward_terms(w, TERMS_V2, RewardInputs(newly.sum(axis=1), progress, contacts, own))
    for k in range(2):
        one = reward_terms(w, TERMS_V2, RewardInputs(int(newly[k].sum()), progress[k], contacts[k],
                                                    own_visits(newly[k], visitor[k], owner, 3)))
        assert list(one) == list(block) and all(np.array_equal(one[t], block[t][k]) for t in one)
    assert block["kpoi"].tolist() == [[20.0] * 3] * 2 and block["collision"][1].tolist() == [-3.0, 0.0, 0.0]
    assert block["progress"][0].tolist() == [1.0, -0.5, 0.0] and block["own_kpoi"][1].tolist() == [5.0, 0.0, 5.0]
    assert block["time"].tolist() == [[-0.01] * 3] * 2


# ---------------------------------------------------------------- metrics
def _world(seed):
    g = np.random.default_rng(seed)
    n = 4
    before = np.column_stack([g.uniform(0, 5, (n, 2)), g.uniform(-3, 3, n)])
    true = before + g.normal(0, 0.1, (n, 3))
    est = true + g.normal(0, 0.05, (n, 3))
    m = EpisodeMetrics(2, n, 4.0, 0.5, path_lengths=g.uniform(0, 3, n).tolist())
    progress = SimpleNamespace(visited=np.array([True, seed % 2 == 0]), done=seed % 2 == 0,
                               visit_time=np.array([1.0, 2.5]))
    pred = np.array([-1, 0, 1, -1]) if seed % 2 else np.array([-1, 0, -1, 2])
    team = SimpleNamespace(predecessor=pred, leader=pred < 0, messages=Counter({"split": 0, "pose": seed}),
                           splits=Counter({"kinect": seed}))
    contacts = (g.integers(0, 3, n), g.integers(0, 2, n))
    return m, before, true, est, progress, team, contacts


class HalfPlane:
    def in_view(self, xy):
        return xy[:, 0] < 2.5


def test_record_steps_of_two_worlds_are_two_record_step_calls():
    formation = SimpleNamespace(offset=0.1, spacing=0.6, bearing_deg=180.0)
    worlds = [_world(1), _world(2)]
    worlds[1][2][[0, 2], 0] = [3.0, 4.0]  # both leaders of world 1 out of the Kinects' view
    alone = copy.deepcopy(worlds)
    for m, before, true, est, progress, team, contacts in alone:
        for _ in range(2):
            record_step(m, before, true, time=0.3, progress=progress, estimate=est, new_contacts=contacts, team=team,
                        formation=formation, kinects=HalfPlane(), control_dt=0.1)
    ms, befores, trues, ests, progs, teams, contacts = zip(*worlds, strict=True)
    for _ in range(2):
        record_steps(list(ms), np.stack(befores), np.stack(trues), times=[0.3, 0.3], progress=progs,
                     estimates=np.stack(ests), new_contacts=tuple(np.stack(c) for c in zip(*contacts, strict=True)),
                     teams=teams, formation=formation, kinects=HalfPlane(), control_dt=0.1)
    for m, ref in zip(ms, alone, strict=True):
        assert m.summary() == ref[0].summary() and m.unseen_leader_time == ref[0].unseen_leader_time
    assert ms[0].makespan is None and ms[1].makespan == 2.5
    assert list(ms[1].messages.items()) == [("pose", 2), ("split", 0)]  # sorted, a zero count kept
    for m, _, true, _, _, team, _ in worlds:  # by value: 2 equal steps
        dl, dpsi = formation_errors(true, team.predecessor, 0.1, 0.6, math.pi)
        assert m.formation_error_l == pytest.approx(math.sqrt(np.mean(dl ** 2)), rel=1e-12)
        assert m.formation_error_psi == pytest.approx(math.sqrt(np.mean(dpsi ** 2)), rel=1e-12)
        unseen = np.count_nonzero(team.leader & (true[:, 0] >= 2.5))
        assert m.unseen_leader_time == pytest.approx(2 * 0.1 * unseen) and m.kinect_splits == team.splits["kinect"]
    assert round(ms[1].unseen_leader_time / 0.2) == 2


def test_path_and_error_sums_by_value_and_as_numpy_sums():
    before = np.zeros((2, 2, 3))
    true = np.array([[[3.0, 4.0, 0.0], [0.0, 1.0, 0.0]], [[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]]])
    est = true + np.array([[[0.3, 0.4, 9.0], [0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]]])
    paths, sq = np.array([[1.0, 2.0], [0.0, 0.5]]), np.full(2, np.nan)
    step_kernels.path_and_error_sums(before, true, est, paths, sq)  # paths in place, sq written
    assert paths.tolist() == [[6.0, 3.0], [0.0, 0.5 + math.sqrt(2.0)]] and sq.tolist() == pytest.approx([0.25, 5.0])
    g = np.random.default_rng(3)
    for n in (1, 5, 8, 15, 64, 65, 100, 129, 300, 1000, 5000):
        x = g.normal(size=n) ** 2 * 10
        assert step_kernels.pairwise_sum(x, 0, n) == np.sum(x), n  # numpy's pairwise summation, to the bit


def test_formation_errors_many_is_each_world_alone():
    g = np.random.default_rng(5)
    poses = np.column_stack([g.uniform(-3, 3, (12, 2)), g.uniform(-4, 4, 12)]).reshape(2, 6, 3)
    pred = np.array([[-1, 0, 1, 2, -1, 4], [-1, -1, -1, -1, -1, -1]])
    dl, dpsi, n = formation_errors_many(poses, pred, 0.1, 0.5, math.pi)
    assert n.tolist() == [4, 0] and not dl[1].any() and not dl[0, 4:].any()
    raw = np.full((2, 6), 7.0), np.full((2, 6), 7.0), np.full(2, 9)  # the kernel writes every entry
    step_kernels.formation_errors_many(poses, pred, 0.1, 0.5, math.pi, *raw)
    assert raw[2].tolist() == [4, 0] and np.array_equal(raw[0], dl) and not raw[1][1].any() and not raw[1][0, 4:].any()
    for k in range(2):
        one = formation_errors(poses[k], pred[k], 0.1, 0.5, math.pi)
        assert np.array_equal(one[0], dl[k, :n[k]]) and np.array_equal(one[1], dpsi[k, :n[k]])


# ---------------------------------------------------------------- observations
def test_fill_scalars_many_is_each_world_alone():
    layout = layout_of((0, 0, 10, 8), 0.5, 1.5, 16, 3.0, 2.5, covariance=True)
    g = np.random.default_rng(0)
    k, n = 2, 5

    def inputs():
        cov = g.normal(size=(k, n, 3, 3)) * 0.1
        return ScalarInputs(np.concatenate([g.uniform(0, 10, (k, n, 2)), g.uniform(-4, 4, (k, n, 1))], axis=2),
                            g.uniform(-0.5, 0.5, (k, n, 2)), g.random((k, n)) < 0.3,
                            np.stack([g.permutation(n) for _ in range(k)]), g.uniform(0, 90, (k, n)),
                            cov @ cov.transpose(0, 1, 3, 2), g.uniform(0, 10, (k, n, 2)), g.uniform(-1, 1, (k, n, 2)),
                            g.uniform(-3, 3, (k, n)), g.random((k, n)) < 0.6, np.array([0.25, 0.5]),
                            np.array([0.125, 1.0]))

    block = inputs()
    got = np.zeros((k, n, layout.size), dtype=np.float32)
    layout.fill_scalars_many(got, block)
    for j in range(k):
        one = np.zeros((n, layout.size), dtype=np.float32)
        layout.fill_scalars(one, ScalarInputs(*(x[j] for x in block)))
        assert np.array_equal(got[j], one)
    assert got[1, :, layout.slices["kpois_visited"]].ravel().tolist() == [0.5] * n
    assert got[0, :, layout.slices["time"]].ravel().tolist() == [0.125] * n


# ---------------------------------------------------------------- whole phases
def _two_worlds(scenario, overrides=None):
    envs = [parcover_env.parallel_env(scenario, overrides=overrides) for _ in range(2)]
    for seed, e in enumerate(envs):
        e.reset(seed=seed)
        rng = np.random.default_rng(seed)
        for _ in range(5 + 10 * seed):  # different states
            e.step({a: rng.uniform(-1, 1, e.action_space(a).shape).astype(np.float32) for a in e.agents})
    return envs


@pytest.mark.parametrize("scenario, overrides", [("office", None), ("tree", {"observation": {"version": 2}}),
                                                 ("office", {"observation": {"scan": {"enabled": True}}}),
                                                 ("office", {"rewards": {"uncertainty": -1.0}})])
def test_phases_of_two_worlds_are_each_world_alone(scenario, overrides):
    envs = _two_worlds(scenario, overrides)
    alone = copy.deepcopy(envs)
    rng = np.random.default_rng(9)
    acts = [{a: rng.uniform(-1, 1, e.action_space(a).shape).astype(np.float32) for a in e.agents} for e in envs]
    obs, out = pipeline.step(envs, acts)
    outs = [outputs_phase.agent_dicts(e.possible_agents, out, k) for k, e in enumerate(envs)]
    for k, e in enumerate(alone):
        obs1, one = pipeline.step([e], [acts[k]])
        out1 = [outputs_phase.agent_dicts(e.possible_agents, one)]
        assert np.array_equal(obs[k], obs1[0])
        assert outs[k][:3] == out1[0][:3]
        infos, infos1 = outs[k][3], out1[0][3]
        assert list(infos) == list(infos1)
        for a in infos:
            assert list(infos[a]) == list(infos1[a])
            assert all(np.array_equal(infos[a][key], infos1[a][key]) for key in infos[a])
        assert envs[k].metrics.summary() == e.metrics.summary()


def test_info_keys_in_their_fixed_order():
    env = parcover_env.parallel_env("office", overrides={"observation": {"version": 2, "scan": {"enabled": True}}})
    env.reset(seed=0)
    true = env.true_poses()[None]
    terms = [[[0.5] * env.n_robots] for _ in env.terms]
    info = outputs_phase.infos([env], true, terms, [False])[0]["robot_1"]
    keys = list(info)
    assert keys[:5] == ["reward_own_kpoi", "reward_kpoi", "reward_progress", "reward_time", "reward_collision"]
    assert keys[-4:] == ["pose_error", "heading_error", "sonar_fix", "route_done"]
    assert all(k.startswith("metrics/") for k in keys[5:-4]) and info["metrics/ended"] == 0.0
    error = np.hypot(*(env.estimate - true[0])[1, :2])
    assert info["reward_time"] == 0.5 and info["pose_error"] == pytest.approx(error)
    ended = outputs_phase.infos([env], true, terms, [True])[0]["robot_0"]
    assert list(ended) == keys and ended["metrics/ended"] == 1.0
    assert "active" not in info
    slot = outputs_phase.infos([env], true, terms, [False], active=True)[0]["robot_1"]  # a VecEnv's slot
    assert list(slot) == [*keys, "active"] and slot["active"] is True and slot["pose_error"] == info["pose_error"]


def test_infos_of_two_worlds_by_value_one_dict_per_agent():
    envs = _two_worlds("office", {"observation": {"version": 2, "scan": {"enabled": True}}})
    k_worlds, n = len(envs), envs[0].n_robots
    envs[1].progress.visited[:] = True  # by hand: every route of world 1 done
    true = np.stack([e.true_poses() for e in envs]) + [0.03, -0.04, 0.5]  # off the estimates by hand
    terms = [100.0 * i + 10.0 * np.arange(k_worlds)[:, None] + np.arange(n) for i in range(len(envs[0].terms))]
    infos = outputs_phase.infos(envs, true, terms, [False, True])
    assert len({id(info) for world in infos for info in world.values()}) == k_worlds * n  # SB3 writes into each
    for k, (e, world) in enumerate(zip(envs, infos, strict=True)):
        assert list(world) == e.agents
        alone = outputs_phase.infos([e], true[k:k + 1], [t[k:k + 1] for t in terms], [k == 1])[0]
        for j, (a, info) in enumerate(world.items()):
            assert [info[f"reward_{t}"] for t in e.terms] == [100.0 * i + 10.0 * k + j for i in range(len(e.terms))]
            d = e.estimate[j] - true[k, j]
            assert info["pose_error"] == math.hypot(d[0], d[1])
            assert info["heading_error"] == pytest.approx(abs(math.remainder(d[2], 2 * math.pi)), abs=1e-12)
            assert info["sonar_fix"] == e.scanner.outcome[j] and info["metrics/ended"] == float(k == 1)
            assert list(info) == list(alone[a])
            assert all(np.array_equal(info[x], alone[a][x], equal_nan=True) for x in info)
        paths = [info["metrics/path_lengths"] for info in world.values()]
        assert all(p is paths[0] for p in paths)  # one array per world, its agents share it
        np.testing.assert_array_equal(paths[0], e.metrics.path_lengths if k == 1 else np.zeros(n))
    assert infos[0]["robot_0"]["metrics/path_lengths"] is not infos[1]["robot_0"]["metrics/path_lengths"]
    done = [[info["route_done"] for info in w.values()] for w in infos]
    assert done[1] == [1.0] * n and done[0] != done[1]
    assert done == target_kpois(envs[0].route_facts, np.stack([e.progress.visited for e in envs]))[1].tolist()


def test_score_state_starts_without_contacts_and_gather_copies():
    st = score_phase.ScoreState.start(np.array([3.0, 4.0]))
    assert st.contacts[0].tolist() == [0, 0] and st.remaining.tolist() == [3.0, 4.0]
    a = np.zeros(2)
    assert score_phase.gather([a])[0] is not a and not np.shares_memory(score_phase.gather([a]), a)
    assert np.shares_memory(score_phase.rows([a]), a) and not np.shares_memory(score_phase.rows([a, a]), a)


def test_scores_carry_a_copy_of_the_estimates_and_the_visits_to_the_later_phases():
    env = parcover_env.parallel_env("office")
    env.reset(seed=1)
    acted = act_phase.act([env], [{a: np.array([0.5, 0.1], np.float32) for a in env.agents}])
    true = acted.true
    scores = score_phase.score([env], acted)
    assert np.array_equal(scores.estimates[0], env.estimate) and not np.shares_memory(scores.estimates, env.estimate)
    assert np.array_equal(scores.visited[0], env.progress.visited)
    twin = copy.deepcopy(env)
    obs = pipeline.observe([env], true, scores)
    assert not np.shares_memory(env.camera_view.estimates, env.estimate)
    assert np.array_equal(obs, pipeline.observe([twin], true))  # read from the worlds: the same


def test_infos_take_the_team_terms_from_the_first_agent_and_reward_terms_make_them_one_per_world():
    envs = _two_worlds("office")
    k_worlds, n = len(envs), envs[0].n_robots
    true = np.stack([e.true_poses() for e in envs])
    terms = [np.arange(k_worlds * n, dtype=float).reshape(k_worlds, n) + 100 * i for i in range(len(envs[0].terms))]
    terms[2][1, 0] = -0.0  # world 1's time term: its first agent's, sign and all
    team = ("kpoi", "time")
    infos = outputs_phase.infos(envs, true, terms, [False, False], team_terms=team)
    plain = outputs_phase.infos(envs, true, terms, [False, False])
    for k, (world, ref) in enumerate(zip(infos, plain, strict=True)):
        for j, a in enumerate(world):
            assert list(world[a]) == list(ref[a])
            got = [world[a][f"reward_{t}"] for t in envs[0].terms]
            col = [j if t not in team else 0 for t in envs[0].terms]
            assert got == [terms[i][k, c] for i, c in enumerate(col)]
            assert all(np.array_equal(world[a][x], ref[a][x]) for x in ref[a] if not x.startswith("reward_"))
    assert math.copysign(1.0, infos[1]["robot_1"]["reward_time"]) == -1.0  # time: the world's first agent's
    w = SimpleNamespace(kpoi=10.0, own_kpoi=5.0, progress=2.0, time=-0.01, collision=-1.0)
    block = reward_terms(w, TERMS, RewardInputs(np.array([0, 2]), np.ones((2, 3)), np.zeros((2, 3), dtype=int)))
    for t in rewards.TEAM_TERMS:
        assert (block[t].view(np.int64) == block[t][:, :1].view(np.int64)).all(), t


def test_the_score_phase_reads_the_estimates_from_the_act_phases_rows_as_a_copy():
    envs = _two_worlds("office")
    rng = np.random.default_rng(5)
    acts = rng.uniform(-1, 1, (2, envs[0].n_robots, 2)).astype(np.float32)
    acted = act_phase.act(envs, acts)
    rows = acted.rows
    assert rows is envs[0].estimator.act_rows and rows is envs[1].estimator.act_rows
    np.testing.assert_array_equal(rows.odometry.blocks["estimate"], np.stack([e.estimate for e in envs]))
    np.testing.assert_array_equal(acted.true, np.stack([e.true_poses() for e in envs]))
    scores = score_phase.score(envs, acted)
    assert scores.act is rows and not np.shares_memory(scores.estimates, rows.odometry.blocks["estimate"])
    np.testing.assert_array_equal(scores.estimates, np.stack([e.estimate for e in envs]))
