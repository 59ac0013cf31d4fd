"""The pose estimator's public interface: dead reckoning plus fixes from pluggable sources."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.localization.estimator import FixRequest, PoseEstimator


class FixedSource:
    """A third fix source (as a sonar localizer fix will be): robot ``i`` fixed at ``pose`` each step."""

    name = "test"

    def __init__(self, i, pose, sigma):
        self.i, self.pose, self.covariance = i, np.asarray(pose, float), np.diag([sigma**2, sigma**2, 0.01])
        self.requests: list[FixRequest] = []
        self.resets = 0

    def reset(self, rng):
        self.resets += 1

    def fixes(self, request, rng):
        self.requests.append(request)
        return {self.i: self.pose}


def test_update_dead_reckons_then_applies_every_source():
    env = parcover_env.parallel_env("office", overrides={"observation": {"pose_source": "odometry"}})
    env.reset(seed=0)
    s, true = env.scenario, env.true_poses()
    source = FixedSource(1, [1.0, 2.0, 0.5], 0.1)
    est = PoseEstimator(s, true, np.random.default_rng(0), [source])
    assert source.resets == 1
    np.testing.assert_array_equal(est.estimate, true)
    fixed = est.update(true, np.zeros((2, 2)), None, 0.1, np.array([True, False]), np.random.default_rng(1))
    assert list(fixed) == ["test"] and list(fixed["test"]) == [1]
    np.testing.assert_array_equal(est.estimate[1], [1.0, 2.0, 0.5])
    np.testing.assert_array_equal(est.covariance[1], source.covariance)
    assert est.fix_age.tolist() == [pytest.approx(s.physics.control_dt), 0.0]
    req = source.requests[0]
    assert req.time == 0.1 and req.leaders.tolist() == [True, False] and req.true is true
    est.fix(0, [3.0, 3.0, 0.0])
    assert est.estimate[0].tolist() == [3.0, 3.0, 0.0] and not est.covariance[0].any()


def test_a_third_source_plugs_into_the_env_without_touching_the_stepper():
    env = parcover_env.parallel_env("office")
    env.fix_sources.append(FixedSource(1, [2.5, 3.0, 0.0], 0.05))
    env.reset(seed=0)
    obs, *_ = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    lay = env.layout
    assert lay.get(obs["robot_1"], "x")[0] == np.float32(2.5) and lay.get(obs["robot_1"], "y")[0] == np.float32(3.0)
    assert lay.get(obs["robot_1"], "fix_age")[0] == 0.0
    assert lay.get(obs["robot_1"], "sigma_major")[0] == np.float32(0.05)
    np.testing.assert_array_equal(env.pose_estimates()[1], [2.5, 3.0, 0.0])
