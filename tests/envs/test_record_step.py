"""``metrics.record_step``: one control step's contribution to the episode metrics, pinned by value on
a hand-built situation (two robots, a leader and its follower, one Kinect footprint)."""

from __future__ import annotations

import math
from collections import Counter
from types import SimpleNamespace

import numpy as np
import pytest

from parcover_env.mission.metrics import EpisodeMetrics, record_step


class Footprint:
    """A Kinect system whose footprint is x < 1 m."""

    def in_view(self, xy: np.ndarray) -> np.ndarray:
        return xy[:, 0] < 1.0


def situation(done: bool = False):
    m = EpisodeMetrics(n_kpois=2, n_robots=2, c_max=4.0, max_speed=0.2, path_lengths=[1.0, 2.0])
    before = np.array([[0.0, 0.0, 0.0], [-0.5, 0.0, 0.0]])
    true = np.array([[3.0, 4.0, 0.0], [-0.5, 0.5, 0.0]])  # robot 0 moved 5 m (leader, out of view), robot 1 0.5 m
    estimate = true + np.array([[0.3, 0.4, 0.0], [0.0, 0.0, 0.0]])  # robot 0 off by 0.5 m
    progress = SimpleNamespace(visited=np.array([True, done]), done=done, visit_time=np.array([3.0, 7.5]))
    team = SimpleNamespace(predecessor=np.array([-1, 0]), leader=np.array([True, False]),
                           messages=Counter({"waypoint": 2, "split": 1}), splits=Counter({"kinect": 3, "odometry": 1}))
    formation = SimpleNamespace(offset=0.0, spacing=3.5, bearing_deg=180.0)
    return m, before, true, dict(time=12.5, progress=progress, estimate=estimate,
                                 new_contacts=(np.array([1, 2]), np.array([1, 1])), team=team,
                                 formation=formation, kinects=Footprint(), control_dt=0.1)


def test_one_step_adds_paths_contacts_errors_messages_splits_and_unseen_time():
    m, before, true, kw = situation()
    record_step(m, before, true, **kw)
    assert m.path_lengths == [6.0, 2.5]
    assert (m.steps, m.time, m.kpois_visited) == (1, 12.5, 1)
    assert (m.wall_collisions, m.robot_collisions) == (3, 1)  # a robot-robot contact counts for both robots
    assert m.localization_error == pytest.approx(math.sqrt(0.25 / 2))
    follower_to_leader = math.hypot(3.0 - -0.5, 4.0 - 0.5)  # l of the follower (offset 0)
    assert m.formation_error_l == pytest.approx(abs(follower_to_leader - 3.5))
    assert m.messages == {"split": 1, "waypoint": 2}
    assert (m.kinect_splits, m.odometry_splits) == (3, 1)
    assert m.unseen_leader_time == pytest.approx(0.1)  # the leader at x = 3 m is outside the footprint
    assert m.makespan is None


def test_without_kinects_every_leader_is_unseen_and_the_makespan_is_the_last_visit():
    m, before, true, kw = situation(done=True)
    kw["kinects"] = None
    record_step(m, before, true, **kw)
    record_step(m, true, true, **kw)
    assert m.unseen_leader_time == pytest.approx(0.2)
    assert m.makespan == 7.5 and m.kpois_visited == 2
    assert m.path_lengths == [6.0, 2.5]  # standing still adds nothing
