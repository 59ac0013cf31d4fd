"""Alg. 1 bookkeeping: one column at the start, splits at the TP, promotions, message counts."""

from __future__ import annotations

import numpy as np

from parcover_env.env.team import Team
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
