"""Alg. 1 bookkeeping: one column at the start, splits at the TP, promotions, message counts."""

from __future__ import annotations

import numpy as np

from parcover_env.mission.metrics import episode_metrics
from parcover_env.mission.team import Team
from parcover_env.planning import plan_scenario
from parcover_env.scenarios import load_scenario


def test_office_team_splits_once_at_its_tp():
    s = load_scenario("office")
    plan = plan_scenario(s, 2)
    team = Team(plan)
    assert team.groups == [(0, 2)] and team.leader.tolist() == [True, False]
    assert team.predecessor.tolist() == [-1, 0]
    tp = plan.turning_points[0]
    xy = np.array([[9.0, 9.0], [9.0, 9.0]])
    assert team.update(xy, np.array([tp.distance - 0.5, 0.0])) == []
    events = team.update(xy, np.array([tp.distance, 0.0]))
    assert len(events) == 1 and team.groups == [(0, 1), (1, 2)]
    assert team.leader.tolist() == [True, True] and team.predecessor.tolist() == [-1, -1]
    assert team.messages == {"split": 2, "promotion": 1}
    team.count_waypoints(np.array([True, True]))
    assert team.messages["waypoint"] == 2


def test_individual_mode_has_no_formations():
    plan = plan_scenario(load_scenario("tree"), 15)
    team = Team(plan, mode="individual")
    assert team.leader.all() and (team.predecessor == -1).all()
    assert team.update(np.zeros((15, 2)), np.full(15, 1e9)) == []


def _office_team():
    s = load_scenario("office")
    plan = plan_scenario(s, 2)
    return Team(plan), plan.turning_points[0]


def test_alg1_split_waits_for_the_kinect_detection_at_the_tp():
    """Kinects in the scenario: the leader's own estimate at the TP does not split the group; the
    Kinect system detecting it there does (seed A Alg. 1)."""
    team, tp = _office_team()
    at_tp = np.array([tp.position, tp.position])
    progress = np.array([tp.distance, 0.0])
    in_view = np.array([True, True])
    assert team.update(at_tp, progress, fixes={}, in_view=in_view) == []  # in view, not detected yet
    far_fix = {0: np.array([tp.position[0] + 1.0, tp.position[1], 0.0])}
    assert team.update(at_tp, np.array([0.0, 0.0]), fixes=far_fix, in_view=in_view) == []  # seen elsewhere
    events = team.update(at_tp, np.array([0.0, 0.0]), fixes={0: np.array([*tp.position, 0.0])}, in_view=in_view)
    assert len(events) == 1 and events[0]["source"] == "kinect" and team.groups == [(0, 1), (1, 2)]
    assert team.splits == {"kinect": 1}


def test_alg1_leader_out_of_view_splits_on_odometry_and_is_counted():
    team, tp = _office_team()
    at_tp = np.array([tp.position, tp.position])
    events = team.update(at_tp, np.array([0.0, 0.0]), fixes={}, in_view=np.array([False, False]))
    assert len(events) == 1 and events[0]["source"] == "odometry"
    assert team.splits == {"odometry": 1} and team.groups == [(0, 1), (1, 2)]


def test_env_records_kinect_splits_and_unseen_leader_time():
    """Office: one Kinect sees the start, the TP and both KPOIs, so the only split is the Kinect's
    and no leader is ever out of view; with the Kinect moved away the split falls back on odometry."""
    import parcover_env
    from parcover_env.expert import expert_for

    def run(overrides):
        env = parcover_env.parallel_env("office", overrides=overrides, preset="ideal")
        obs, _ = env.reset(seed=0)
        policy = expert_for(env)
        while env.agents:
            obs, _, _, _, infos = env.step(policy.act(obs))
        return episode_metrics(next(iter(infos.values())))

    m = run(None)
    assert m["success"] and m["kinect_splits"] == 1 and m["odometry_splits"] == 0
    assert m["unseen_leader_time"] == 0.0
    blind = run({"localization": "both", "kinects": [{"name": "A", "position": [1.6, 0.5], "height": 3.9,
                                                      "yaw_deg": 90}]})
    assert blind["odometry_splits"] == 1 and blind["kinect_splits"] == 0 and blind["unseen_leader_time"] > 1.0
