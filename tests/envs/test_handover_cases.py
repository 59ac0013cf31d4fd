"""Alg. 1's env side (Min, Fehr & Papanikolopoulos) on hand-built cases: a leader at its TP inside a
Kinect footprint but not detected this step waits for the detection; out of every footprint it
splits on its estimate; a camera view of ``K`` worlds gives world ``k`` its own rows."""

from __future__ import annotations

import numpy as np

import parcover_env
from parcover_env.mission.team import CameraView, Team, update_team, update_teams
from parcover_env.sensors.relative import RelativeReading


class Kinects:
    """Kinects without fixes this step whose footprints hold every point (``seen``) or none."""

    def __init__(self, seen: bool):
        self.seen = seen
        self.last_fixes: dict = {}
        self.asked: list[np.ndarray] = []
        self.handed: list[dict] = []

    def in_view(self, xy):
        self.asked.append(np.array(xy))
        return np.full(len(xy), self.seen)

    def hand_over(self, poses, estimates):
        self.handed.append(poses)


def _at_tp():
    plan = parcover_env.parallel_env("office").plan
    tp = plan.turning_points[0]
    est = np.zeros((plan.r, 3))
    est[:, :2] = tp.position
    return Team(plan, reach_tol=0.2), est


def test_a_leader_in_view_without_a_fix_waits_and_out_of_view_splits_on_its_estimate():
    team, est = _at_tp()
    kin = Kinects(seen=True)
    update_team(team, kin, est, np.zeros(team.n), None)
    assert team.groups == [(0, team.n)] and team.splits == {}  # waits for the Kinect to detect it
    assert len(kin.asked) == 1 and kin.asked[0].tolist() == [est[0, :2].tolist()]  # asked about the leader only
    team, est = _at_tp()
    update_teams([team], [Kinects(seen=True)], est[None], np.zeros((1, team.n)), lambda k: None)
    assert team.groups == [(0, team.n)]
    update_team(team, Kinects(seen=False), est, np.zeros(team.n), None)
    assert team.splits == {"odometry": 1} and len(team.groups) == 2


def test_a_leader_with_a_fix_is_not_looked_up_in_the_footprints():
    team, est = _at_tp()
    kin = Kinects(seen=True)
    kin.last_fixes = {0: est[0].copy()}
    update_team(team, kin, est, np.zeros(team.n), None)
    assert kin.asked == [] and team.splits == {"kinect": 1}


def test_select_gives_world_k_its_rows():
    reading = RelativeReading(np.arange(12.0).reshape(2, 3, 2), np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]]),
                              np.array([[True, False, True], [False, True, False]]))
    view = CameraView(np.array([[-1, 0, 1], [-1, -1, 0]]), reading, np.arange(18.0).reshape(2, 3, 3))
    one = view.select(1)
    assert one.predecessor.tolist() == [-1, -1, 0]
    assert one.reading.rel_xy.tolist() == [[6.0, 7.0], [8.0, 9.0], [10.0, 11.0]]
    assert one.reading.rel_heading.tolist() == [0.4, 0.5, 0.6]
    assert one.reading.visible.tolist() == [False, True, False]
    assert one.estimates.tolist() == np.arange(9.0, 18.0).reshape(3, 3).tolist()
