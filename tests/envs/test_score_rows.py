"""The score phase's per-world state as rows of shared blocks (:mod:`parcover_env.envs.score_rows`)
and the compiled calls over them: the metrics' sums (:func:`step_kernels.record_many`) by value on a
hand-built step, ``K = 2`` worlds equal to two ``K = 1`` calls, copies and pickles of owners that
hold row views."""

from __future__ import annotations

import copy
import math
import pickle

import numpy as np
import pytest

import parcover_env
from parcover_env.envs import metrics, step_kernels
from parcover_env.envs.metrics import EpisodeMetrics
from parcover_env.envs.score_rows import shared_rows
from parcover_env.envs.team import TEAM_ROWS, Team
from parcover_env.envs.world_rows import SharedRows
from parcover_env.geometry import wrap_angle
from parcover_env.geometry.row_owner import RowOwner


class Owner:
    def __init__(self, a, b):
        self.a, self.b, self.rows = np.array(a, dtype=float), np.array(b, dtype=np.int64), None

    def __getstate__(self):
        return {**self.__dict__, "rows": None}


def test_shared_rows_attach_reuse_and_adopt_again():
    x, y = Owner([1.0, 2.0], [3]), Owner([4.0, 5.0], [6])
    rows = shared_rows([x, y], ("a", "b"))
    assert rows.blocks["a"].tolist() == [[1.0, 2.0], [4.0, 5.0]] and rows.blocks["b"].tolist() == [[3], [6]]
    assert x.rows is rows and y.rows is rows and np.shares_memory(x.a, rows.blocks["a"])
    rows.blocks["a"] += 1.0  # one call on the block updates every owner
    assert x.a.tolist() == [2.0, 3.0] and y.a.tolist() == [5.0, 6.0]
    assert shared_rows([x, y], ("a", "b")) is rows  # reused while attached
    z = Owner([7.0, 8.0], [9])  # a world reset since: a new owner takes row 1
    assert shared_rows([x, z], ("a", "b")) is rows
    assert rows.blocks["a"][1].tolist() == [7.0, 8.0] and y.a.tolist() == [5.0, 6.0]
    assert not np.shares_memory(y.a, rows.blocks["a"])  # the old owner keeps its values, as its own array
    x.a = np.array([0.5, 0.25])  # rebound by a per-world method: copied in again
    shared_rows([x, z], ("a", "b"))
    assert rows.blocks["a"][0].tolist() == [0.5, 0.25] and np.shares_memory(x.a, rows.blocks["a"])
    one = shared_rows([z], ("a", "b"))  # another K: rows of its own
    assert one is not rows and one.size == 1 and z.rows is one and one.blocks["a"].tolist() == [[7.0, 8.0]]
    for c in (copy.deepcopy(x), pickle.loads(pickle.dumps(x))):
        assert c.rows is None and c.a.tolist() == [0.5, 0.25] and not np.shares_memory(c.a, rows.blocks["a"])


def test_metric_totals_are_the_kernels_columns():
    assert metrics.TOTALS == step_kernels.METRIC_TOTALS


def _step(true, predecessor, visited, visit_time, wall, robot, unseen, time):
    k, n = predecessor.shape
    est = true.copy()
    est[1, 0, :2] += [0.3, 0.4]  # world 1's robot 0 estimated 0.5 m off
    return step_kernels.MetricsStep(np.zeros((k, n, 3)), true, est, predecessor, visited, visit_time, wall,
                                    robot, unseen, time)


def test_record_many_by_value():
    true = np.array([[[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    step = _step(true, np.array([[-1, 0], [-1, -1]]), np.array([[True, True], [True, False]]),
                 np.array([[1.0, 2.5], [0.5, np.nan]]), np.array([[2, 0], [0, 1]]), np.array([[1, 1], [0, 0]]),
                 np.array([1, 0]), np.array([0.3, 0.3]))
    totals = np.zeros((2, 12))
    totals[:, -1] = np.nan
    paths = np.array([[1.0, 0.0], [0.0, 0.0]])
    step_kernels.record_many(totals, paths, step, (0.0, 4.0, math.pi), 0.1)
    assert paths.tolist() == [[6.0, 0.0], [1.0, 1.0]]
    t = dict(zip(step_kernels.METRIC_TOTALS, totals[0].tolist(), strict=True))
    # follower 1 at the origin, 5 m from its leader at (3, 4): l - l_d = 1; the bearing of (-3, -4) minus pi,
    # wrapped, is atan(4 / 3)
    assert t["sq_l"] == 1.0 and t["sq_psi"] == pytest.approx(math.atan(4 / 3) ** 2, rel=1e-14) and t["n_form"] == 1
    raw = math.atan2(-4.0, -3.0) - math.pi
    assert t["sq_psi"] == np.sum(wrap_angle(np.array([raw])) ** 2)
    assert (t["steps"], t["time"], t["kpois_visited"], t["wall_collisions"], t["robot_collisions"]) == (1, 0.3, 2, 2, 1)
    assert (t["sq_err"], t["n_err"], t["unseen_leader_time"], t["makespan"]) == (0.0, 2, 0.1, 2.5)
    u = dict(zip(step_kernels.METRIC_TOTALS, totals[1].tolist(), strict=True))
    assert (u["n_form"], u["sq_l"], u["kpois_visited"], u["wall_collisions"]) == (0, 0, 1, 1)
    assert u["unseen_leader_time"] == 0
    assert math.isnan(u["makespan"]) and u["sq_err"] == pytest.approx(0.25) and u["n_err"] == 2
    step.visit_time[0, 1] = 9.0  # the makespan is set once
    step_kernels.record_many(totals, paths, step, (0.0, 4.0, math.pi), 0.1)
    assert totals[0, -1] == 2.5 and totals[0, 0] == 2 and totals[0, 9] == 2 and totals[0, 10] == pytest.approx(0.2)
    assert totals[0, 1:5].tolist() == [0.3, 2, 4, 2]  # the time and visits set, the contacts summed
    assert paths.tolist() == [[11.0, 0.0], [2.0, 2.0]] and totals[0, 6] == 4
    assert totals[1, 5] == pytest.approx(0.5) and totals[1, 6] == 4  # squared errors summed over steps


def test_episode_metrics_rows_survive_copies_and_are_adopted_after_a_reset():
    ms = [EpisodeMetrics(2, 2, 4.0, 0.5, path_lengths=[1.0, 2.0]) for _ in range(2)]
    rows = shared_rows(ms, ("totals", "paths"))
    rows.blocks["paths"] += 1.0
    rows.blocks["totals"][:, 0] = 3.0
    c = copy.deepcopy(ms[1])
    assert c.rows is None and c.path_lengths == [2.0, 3.0] and c.steps == 3
    fresh = EpisodeMetrics(2, 2, 4.0, 0.5)
    assert shared_rows([ms[0], fresh], ("totals", "paths")) is rows
    assert fresh.steps == 0 and ms[1].steps == 3 and rows.blocks["totals"][:, 0].tolist() == [3.0, 0.0]
    assert pickle.loads(pickle.dumps(ms[0])).summary() == ms[0].summary()


def test_metrics_link_the_teams_counters_once_and_a_copied_world_keeps_the_link():
    import parcover_env

    env = parcover_env.parallel_env("office")
    env.reset(seed=0)
    assert env.metrics.messages == {} and env.metrics.kinect_splits == 0  # nothing recorded yet
    env.step({a: np.array([0.5, 0.0], np.float32) for a in env.agents})
    m, team = env.metrics, env.team
    assert m.team_counts[0] is team.messages and m.team_counts[1] is team.splits
    team.messages["split"] += 2
    team.splits["odometry"] += 1
    assert m.messages["split"] == team.messages["split"] and m.odometry_splits == team.splits["odometry"] == 1
    assert list(m.messages) == sorted(team.messages)
    c = copy.deepcopy(env)
    assert c.metrics.team_counts[0] is c.team.messages and c.metrics.summary() == m.summary()


def test_each_world_reads_its_row_of_the_camera_views_and_a_copy_keeps_its_own_row_only():
    import parcover_env
    from parcover_env.envs import stepper

    envs = [parcover_env.parallel_env("office") for _ in range(3)]
    for seed, e in enumerate(envs):
        e.reset(seed=seed)
    alone = copy.deepcopy(envs)
    acts = [{a: np.array([0.5, 0.1 * k], np.float32) for a in e.agents} for k, e in enumerate(envs)]
    stepper.step(envs, acts)
    for k, (e, one) in enumerate(zip(envs, alone, strict=True)):
        stepper.step([one], [acts[k]])
        assert e.camera_views is envs[0].camera_views and e.camera_index == k
        view, ref = e.camera_view, one.camera_view
        assert np.array_equal(view.predecessor, ref.predecessor) and np.array_equal(view.estimates, ref.estimates)
        assert all(np.array_equal(x, y) for x, y in zip(view.reading, ref.reading, strict=True))
        for c in (copy.deepcopy(e), pickle.loads(pickle.dumps(e))):
            assert c.camera_index == 0 and c.camera_views.estimates.shape == (1, e.n_robots, 3)
            assert np.array_equal(c.camera_view.estimates, view.estimates)
            assert not np.shares_memory(c.camera_views.estimates, view.estimates)
    assert np.array_equal(envs[1].camera_view.estimates, envs[1].estimate)  # measured at this step's estimates


def test_score_states_as_shared_rows():
    from parcover_env.envs.score_phase import HELD, ScoreState

    states = [ScoreState.start(np.array([3.0, 4.0])), ScoreState.start(np.array([1.0, 2.0]))]
    held = shared_rows(states, HELD).blocks
    assert held["remaining"].tolist() == [[3.0, 4.0], [1.0, 2.0]] and held["wall"].dtype == np.int64
    held["robot"][1] += [2, 0]
    assert states[1].contacts[1].tolist() == [2, 0] and states[0].contacts[1].tolist() == [0, 0]
    for c in (copy.deepcopy(states[1]), pickle.loads(pickle.dumps(states[1]))):
        assert c.rows is None and c.robot.tolist() == [2, 0] and not np.shares_memory(c.robot, held["robot"])


ROUTE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.5], [2.0, 0.0], [4.0, 0.0]])
KPOIS = np.array([[2.0, 1.5], [4.0, 0.0]])


def _tracker():
    from parcover_env.scenarios.progress import RouteTracker

    return RouteTracker(KPOIS, 0.2, [ROUTE, ROUTE + [0.0, 0.1]], waypoint_tol=0.15, lookahead=0.4)


def test_trackers_stepped_on_shared_rows_are_each_tracker_alone():
    from parcover_env.scenarios.progress import STATE, step_many
    from parcover_env.scenarios.progress_kernel import TrackerRows

    a, b = _tracker(), _tracker()
    for x in np.arange(0.0, 2.05, 0.25):  # world a walks to the foot of the spur, world b stays behind
        a.update(np.array([[x, 0.05], [x - 0.3, 0.1]]), np.array([[x, 0.05], [x - 0.3, 0.1]]), 1.0)
    alone = [copy.deepcopy(a), copy.deepcopy(b)]
    rows = shared_rows([a, b], STATE)
    state = TrackerRows(**rows.blocks)
    true = np.array([[[2.0, 1.45], [0.5, 0.1]], [[0.4, 0.0], [0.2, 0.1]]])  # a's robot 0 reaches KPOI 0
    got = step_many([a, b], true, true + 0.01, [3.0, 4.0], state)
    for k, (t, ref) in enumerate(zip((a, b), alone, strict=True)):
        want = step_many([ref], true[k:k + 1], true[k:k + 1] + 0.01, [3.0 + k])
        assert got.n_new[k] == want.n_new[0] and np.array_equal(got.goals[k], want.goals[0])
        assert np.array_equal(got.remaining[k], want.remaining[0])
        for name in STATE:
            mine, theirs = getattr(t, name), getattr(ref, name)
            assert np.array_equal(mine, theirs, equal_nan=True) and np.shares_memory(mine, rows.blocks[name])
    assert a.visited.tolist() == [True, False] and a.visitor.tolist() == [0, -1] and a.visit_time[0] == 3.0
    assert got.n_new.tolist() == [1, 0] and a.advanced.tolist() == alone[0].advanced.tolist()
    assert rows.blocks["progress"][1].tolist() == b.progress.tolist() and b.progress[0] > 0.0  # b moved on too


class Tracked(RowOwner):
    def __init__(self, a, b):
        self.a, self.b, self.c = np.array(a, dtype=float), np.array(b, dtype=np.int64), 0


def test_a_row_owner_forgets_its_rows_when_a_row_array_is_rebound_only():
    x, y = Tracked([1.0, 2.0], [3]), Tracked([4.0, 5.0], [6])
    rows = shared_rows([x, y], ("a", "b"))
    assert x.rows is rows and y.rows is rows
    x.a += 1.0  # in place: the same view, still attached
    x.c = 5  # not a row array
    assert x.rows is rows and rows.blocks["a"][0].tolist() == [2.0, 3.0]
    x.b = np.array([7])  # rebound: the rows are forgotten, adopted again at the next call
    assert x.rows is None and y.rows is rows
    assert shared_rows([x, y], ("a", "b")) is rows and x.rows is rows
    assert rows.blocks["b"].tolist() == [[7], [6]] and np.shares_memory(x.b, rows.blocks["b"])
    for c in (copy.deepcopy(x), pickle.loads(pickle.dumps(x))):
        assert c.rows is None and c.a.tolist() == [2.0, 3.0] and not np.shares_memory(c.a, rows.blocks["a"])


def test_shared_rows_skip_attaching_only_while_every_owner_holds_its_row(monkeypatch):
    x, y = Tracked([1.0, 2.0], [3]), Tracked([4.0, 5.0], [6])
    rows = shared_rows([x, y], ("a", "b"))
    calls = []
    attach = SharedRows.attach
    monkeypatch.setattr(SharedRows, "attach", lambda self, owners: calls.append(list(owners)) or attach(self, owners))
    assert shared_rows([x, y], ("a", "b")) is rows and calls == []  # all attached: nothing to do
    assert shared_rows([y, x], ("a", "b")) is rows and calls == [[y, x]]  # another order: rows follow it
    assert rows.blocks["a"].tolist() == [[4.0, 5.0], [1.0, 2.0]] and np.shares_memory(y.a, rows.blocks["a"][0])
    z = Tracked([8.0, 9.0], [0])  # a world reset since: a new owner
    assert shared_rows([y, z], ("a", "b")) is rows and len(calls) == 2
    assert x.rows is None and not np.shares_memory(x.a, rows.blocks["a"]) and x.a.tolist() == [1.0, 2.0]
    assert rows.blocks["a"].tolist() == [[4.0, 5.0], [8.0, 9.0]]
    y.a = np.array([0.5, 0.25])  # rebound by a method of its own
    shared_rows([y, z], ("a", "b"))
    assert len(calls) == 3 and rows.blocks["a"][0].tolist() == [0.5, 0.25]


def test_a_split_rebinds_a_teams_arrays_and_its_rows_take_them_in():
    env = parcover_env.parallel_env("tree")
    plan = env.plan
    teams = [Team(plan, reach_tol=0.2), Team(plan, reach_tol=0.2)]
    rows = shared_rows(teams, TEAM_ROWS)
    assert rows.blocks["leader"].tolist() == [[True] + [False] * (plan.r - 1)] * 2
    tp = next(t for t in plan.turning_points if tuple(t.robots) == (0, plan.r))
    est = np.zeros((plan.r, 2))
    est[0] = tp.position  # the leader of world 1's team at its first TP: it splits
    assert teams[1].update(est, np.zeros(plan.r))
    assert teams[1].rows is None and teams[0].rows is rows
    assert shared_rows(teams, TEAM_ROWS) is rows
    np.testing.assert_array_equal(rows.blocks["leader"][1], teams[1].leader)
    np.testing.assert_array_equal(rows.blocks["predecessor"][1], teams[1].predecessor)
    assert rows.blocks["leader"][1].sum() == len(tp.branches) > 1 and rows.blocks["leader"][0].sum() == 1
