"""Episode metrics pinned on hand-built cases the other metric tests leave open: integer inputs, the
``success`` flag read back from an info, and many worlds of one robot each (``K`` > ``N``)."""

from __future__ import annotations

import math
from collections import Counter
from types import SimpleNamespace

import numpy as np
import pytest

from parcover_env.mission.metrics import EpisodeMetrics, episode_metrics, formation_errors, record_step, record_steps

FORMATION = SimpleNamespace(offset=0.0, spacing=1.0, bearing_deg=180.0)


def _team(n: int):
    return SimpleNamespace(predecessor=np.arange(-1, n - 1), leader=np.arange(n) == 0, messages=Counter(),
                           splits=Counter())


def test_integer_start_path_lengths_grow_by_the_float_distance_driven():
    m = EpisodeMetrics(n_kpois=1, n_robots=2, c_max=1.0, max_speed=1.0, path_lengths=[1, 2])
    before = np.zeros((2, 3))
    true = np.array([[0.5, 0.0, 0.0], [0.0, 0.25, 0.0]])
    progress = SimpleNamespace(visited=np.array([False]), visit_time=np.array([np.nan]))
    record_step(m, before, true, time=0.1, progress=progress, estimate=true, new_contacts=(np.zeros(2, int),) * 2,
                team=_team(2), formation=FORMATION, kinects=None, control_dt=0.1)
    assert m.path_lengths == [1.5, 2.25]


def test_formation_errors_of_integer_poses_are_the_float_ones():
    poses = [[0, 0, 0], [-2, 0, 0], [-2, -1, 0]]
    dl, dpsi = formation_errors(poses, [-1, 0, 1], 0.0, 1.0, math.pi)
    np.testing.assert_allclose(dl, [1.0, 0.0], atol=1e-12)  # follower 1 is 2 m behind robot 0, follower 2 1 m
    np.testing.assert_allclose(np.abs(dpsi), [0.0, math.pi / 2], atol=1e-12)
    ref = formation_errors(np.asarray(poses, dtype=float), np.array([-1, 0, 1]), 0.0, 1.0, math.pi)
    assert np.array_equal(dl, ref[0]) and np.array_equal(dpsi, ref[1]) and dl.dtype == float


def test_episode_metrics_reads_success_and_a_failed_missions_makespan_back():
    m = EpisodeMetrics(n_kpois=2, n_robots=1, c_max=2.0, max_speed=0.5)
    m.add_step(4.0, 2, 0.0, 1, 0, 0)
    m.makespan = 3.0
    out = episode_metrics(m.flat(ended=True))
    assert out["success"] is True and out["makespan"] == 3.0 and out["makespan_ratio"] == pytest.approx(0.75)
    m.add_step(5.0, 1, 0.0, 1, 0, 0)
    m.makespan = None
    out = episode_metrics(m.flat(ended=True))
    assert out["success"] is False and out["makespan"] is None and out["makespan_ratio"] is None
    assert episode_metrics(m.flat(ended=False)) is None


def test_many_one_robot_worlds_count_unseen_time_of_their_own_leader_only():
    k = 40  # more worlds than robots: only world 0's leader is out of view
    metrics = [EpisodeMetrics(n_kpois=1, n_robots=1, c_max=1.0, max_speed=1.0) for _ in range(k)]
    true = np.zeros((k, 1, 3))
    true[:, 0, 0] = np.arange(k) + 0.5
    true[0, 0, 0] = -1.0
    kinects = SimpleNamespace(in_view=lambda xy: xy[:, 0] > 0.0)
    record_steps(metrics, true, true, times=[0.1] * k, progress=[None] * k, estimates=true,
                 new_contacts=(np.zeros((k, 1), int), np.zeros((k, 1), int)), teams=[_team(1) for _ in range(k)],
                 formation=FORMATION, kinects=kinects, control_dt=0.1,
                 visits=(np.zeros((k, 1), bool), np.full((k, 1), np.nan)))
    assert [m.unseen_leader_time for m in metrics] == [0.1] + [0.0] * (k - 1)
