"""Failure causes from hand-built episode diagnoses, and one real rollout."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.expert import expert_for
from parcover_env.harness.failures import EpisodeDiagnosis, classify_failure, run_diagnosed


def diag(**kw) -> EpisodeDiagnosis:
    """Two robots, three KPOIs (robot 0 owns 0 and 1, robot 1 owns 2); KPOI 2 unvisited, robot 1
    moving, clear of everything, well localized, and once 0.5 m from KPOI 2."""
    base = dict(visited=np.array([True, True, False]), owner=np.array([0, 0, 1]),
                closest=np.array([0.0, 0.1, 0.5]), moved=np.array([0.0, 1.0]), clearance=np.array([0.3, 0.3]),
                belief_error=np.array([0.05, 0.05]), kpoi_radius=0.4)
    base.update(kw)
    return EpisodeDiagnosis(**base)


@pytest.mark.parametrize(("changes", "cause"), [
    ({}, "timeout"),
    ({"visited": np.array([True, True, True])}, "solved"),
    ({"error": "ValueError: boom"}, "error"),
    ({"belief_error": np.array([0.05, 0.6])}, "localization lost"),
    ({"belief_error": np.array([0.9, 0.05])}, "timeout"),  # robot 0 owns no open KPOI
    ({"moved": np.array([1.0, 0.02]), "clearance": np.array([0.3, 0.005])}, "collision-locked"),
    ({"moved": np.array([1.0, 0.02])}, "stalled"),
    ({"closest": np.array([0.0, 0.1, 0.81])}, "KPOI never approached"),
    ({"closest": np.array([0.0, 0.1, 0.79])}, "timeout"),
])
def test_classify_failure(changes, cause):
    assert classify_failure(diag(**changes)) == cause


def test_run_diagnosed_on_a_solved_episode():
    env = parcover_env.parallel_env("office")
    m, d = run_diagnosed(env, expert_for(env), 0)
    assert m["success"] and m["cause"] == "solved"
    assert d.visited.all() and np.all(d.closest <= env.scenario.kpoi_radius)
    assert np.all(d.belief_error < 0.1) and np.all(d.clearance > 0)
    assert sorted(d.owner.tolist()) == [0, 1]
