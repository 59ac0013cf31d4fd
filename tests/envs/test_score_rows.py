"""The score phase's per-world state as rows of ``(K, ...)`` blocks (:func:`parcover_env.sim.score_phase.score_blocks`)
and the compiled calls over them: the metrics' sums (:func:`step_kernels.record_many`) by value on a
hand-built step, ``K = 2`` worlds equal to two ``K = 1`` calls, a group owning the blocks of its worlds
(views handed out, reused while it holds them, a reset world adopted again), copies and pickles of
worlds that hold row views."""

from __future__ import annotations

import copy
import math
import pickle

import numpy as np
import pytest

import parcover_env
from parcover_env.geometry import wrap_angle
from parcover_env.mission import kernels as step_kernels
from parcover_env.mission import metrics
from parcover_env.mission.team import TEAM_ROWS, Team
from parcover_env.sim.score_phase import PARTS, ScoreGroup, score_blocks
from parcover_env.world.batching import SharedRows


def _worlds(k, scenario="office"):
    worlds = [parcover_env.parallel_env(scenario) for _ in range(k)]
    for seed, w in enumerate(worlds):
        w.reset(seed=seed)
    return worlds


def _arrays(world):
    return {(part, name): getattr(getattr(world, attr), name)
            for part, (attr, names) in PARTS.items() for name in names}


def test_one_worlds_blocks_are_views_of_its_own_arrays():
    w, = _worlds(1)
    blocks = score_blocks([w])
    for (part, name), array in _arrays(w).items():
        block = getattr(blocks, part)[name]
        assert block.shape == (1, *array.shape) and np.shares_memory(block, array)
    assert getattr(w, "score_group", None) is None  # nothing attached, nothing copied


def test_a_group_holds_its_worlds_arrays_as_views_of_its_rows_and_attaches_only_what_changed(monkeypatch):
    worlds = _worlds(2)
    before = [copy.deepcopy(_arrays(w)) for w in worlds]
    blocks = score_blocks(worlds)
    group = worlds[0].score_group
    assert isinstance(group, ScoreGroup) and worlds[1].score_group is group and group.blocks is blocks
    for k, w in enumerate(worlds):
        for (part, name), array in _arrays(w).items():
            block = getattr(blocks, part)[name]
            assert np.shares_memory(array, block[k]) and np.array_equal(array, before[k][part, name], equal_nan=True)
    blocks.held["remaining"] += 1.0  # one call on a block updates every world
    assert worlds[1].score_state.remaining.tolist() == (before[1]["held", "remaining"] + 1.0).tolist()
    calls = []
    monkeypatch.setattr(ScoreGroup, "attach", lambda self, ws: calls.append(list(ws)))
    assert score_blocks(worlds) is blocks and calls == []  # the very worlds and owners: nothing to attach
    assert score_blocks(worlds[::-1]) is blocks and calls == [worlds[::-1]]  # another order: attached again


def test_a_world_reset_since_is_adopted_and_its_old_owners_keep_their_values():
    worlds = _worlds(2)
    blocks = score_blocks(worlds)
    old_team, old_metrics = worlds[1].team, worlds[1].metrics
    blocks.metrics["paths"][1] = [5.0] * worlds[1].n_robots
    worlds[1].reset(seed=7)
    assert score_blocks(worlds) is blocks  # the same group: world 1's new owners take row 1
    assert np.shares_memory(worlds[1].team.leader, blocks.team["leader"]) and blocks.metrics["paths"][1].sum() == 0
    assert old_metrics.path_lengths == [5.0] * worlds[1].n_robots  # the old owner keeps its values, as its own
    assert not np.shares_memory(old_metrics.paths, blocks.metrics["paths"])
    assert not np.shares_memory(old_team.leader, blocks.team["leader"])


def _shares(world, blocks):
    return [np.shares_memory(array, getattr(blocks, part)[name]) for (part, name), array in _arrays(world).items()]


def test_a_world_attached_to_another_group_is_adopted_again_with_its_values():
    a, b, c = _worlds(3)
    blocks = score_blocks([a, b])
    blocks.progress["progress"][0] = 1.5  # a's progress, written through the block
    kept = copy.deepcopy(_arrays(a))
    assert score_blocks([b, c]) is blocks  # b's group fits: b and c take its rows, a gets copies of its values
    assert not any(_shares(a, blocks)) and all(_shares(b, blocks)) and all(_shares(c, blocks))
    assert all(np.array_equal(array, kept[key], equal_nan=True) for key, array in _arrays(a).items())
    assert a.progress.progress.tolist() == [1.5] * a.n_robots
    assert score_blocks([a, b]) is blocks  # a's group still names it, but holds b and c: attached again
    assert all(_shares(a, blocks)) and all(_shares(b, blocks)) and not any(_shares(c, blocks))
    assert blocks.progress["progress"][0].tolist() == [1.5] * a.n_robots


def test_copies_and_pickles_of_a_grouped_world_hold_plain_arrays_of_their_own():
    worlds = _worlds(2)
    blocks = score_blocks(worlds)
    blocks.held["robot"][1] += 2
    for c in (copy.deepcopy(worlds[1]), pickle.loads(pickle.dumps(worlds[1]))):
        assert getattr(c, "score_group", None) is None
        assert c.score_state.robot.tolist() == worlds[1].score_state.robot.tolist()
        for (part, name), array in _arrays(c).items():
            assert not np.shares_memory(array, getattr(blocks, part)[name])


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


def test_record_steps_of_several_worlds_without_blocks_gathers_and_writes_back():
    worlds = _worlds(2)
    twins = copy.deepcopy(worlds)
    w = worlds[0]
    true = np.stack([x.true_poses() for x in worlds])
    moved = true + [0.3, 0.4, 0.0]
    kwargs = dict(times=[0.1, 0.1], progress=[x.progress for x in worlds], estimates=moved,
                  new_contacts=(np.zeros((2, w.n_robots), np.int64), np.zeros((2, w.n_robots), np.int64)),
                  formation=w.scenario.formation, kinects=w.kinects, control_dt=0.1)
    metrics.record_steps([x.metrics for x in worlds], true, moved, teams=[x.team for x in worlds], **kwargs)
    for x in worlds:  # 0.5 m each, written back into each world's own arrays
        assert x.metrics.path_lengths == pytest.approx([0.5] * w.n_robots, abs=1e-15) and x.metrics.steps == 1
    blocks = score_blocks(twins)
    metrics.record_steps([x.metrics for x in twins], true, moved, teams=[x.team for x in twins],
                         sums=blocks.metrics, **kwargs)
    assert [x.metrics.summary() for x in twins] == [x.metrics.summary() for x in worlds]


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
    from parcover_env.sim import pipeline

    envs = [parcover_env.parallel_env("office") for _ in range(3)]
    for seed, e in enumerate(envs):
        e.reset(seed=seed)
    alone = copy.deepcopy(envs)
    acts = [{a: np.array([0.5, 0.1 * k], np.float32) for a in e.agents} for k, e in enumerate(envs)]
    pipeline.step(envs, acts)
    for k, (e, one) in enumerate(zip(envs, alone, strict=True)):
        pipeline.step([one], [acts[k]])
        assert e.camera_views is envs[0].camera_views and e.camera_index == k
        view, ref = e.camera_view, one.camera_view
        assert np.array_equal(view.predecessor, ref.predecessor) and np.array_equal(view.estimates, ref.estimates)
        assert all(np.array_equal(x, y) for x, y in zip(view.reading, ref.reading, strict=True))
        for c in (copy.deepcopy(e), pickle.loads(pickle.dumps(e))):
            assert c.camera_index == 0 and c.camera_views.estimates.shape == (1, e.n_robots, 3)
            assert np.array_equal(c.camera_view.estimates, view.estimates)
            assert not np.shares_memory(c.camera_views.estimates, view.estimates)
    assert np.array_equal(envs[1].camera_view.estimates, envs[1].estimate)  # measured at this step's estimates


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
    rows = SharedRows(2, STATE, a)
    rows.attach([a, b])
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


def test_a_split_writes_a_teams_arrays_in_place_so_its_rows_follow():
    env = parcover_env.parallel_env("tree")
    plan = env.plan
    teams = [Team(plan, reach_tol=0.2), Team(plan, reach_tol=0.2)]
    rows = SharedRows(2, TEAM_ROWS, teams[0])
    rows.attach(teams)
    held = [getattr(teams[1], name) for name in TEAM_ROWS]
    assert rows.blocks["leader"].tolist() == [[True] + [False] * (plan.r - 1)] * 2
    tp = next(t for t in plan.turning_points if tuple(t.robots) == (0, plan.r))
    est = np.zeros((plan.r, 2))
    est[0] = tp.position  # the leader of world 1's team at its first TP: it splits
    assert teams[1].update(est, np.zeros(plan.r))
    assert all(getattr(teams[1], name) is a for name, a in zip(TEAM_ROWS, held, strict=True))  # not rebound
    assert rows.attached(1, teams[1]) and rows.attached(0, teams[0])
    assert rows.blocks["leader"][1].sum() == len(tp.branches) > 1 and rows.blocks["leader"][0].sum() == 1
    np.testing.assert_array_equal(rows.blocks["predecessor"][1], teams[1].predecessor)
    assert np.isnan(rows.blocks["tp_ahead"][1][0]).all() or rows.blocks["tp_ahead"][1][0, 2] > tp.distance
