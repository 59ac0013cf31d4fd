"""Odometry: exact without noise, drifting with it, deterministic per seed."""

from __future__ import annotations

import numpy as np

from parcover_env.config import OdometryConfig
from parcover_env.sensors.odometry import Odometry


def _drive(cfg, seed, steps=200):
    rng = np.random.default_rng(seed)
    pose = np.array([[0.0, 0.0, 0.0]])
    odo = Odometry(cfg, pose)
    for _ in range(steps):  # a circle: 0.03 m and 0.02 rad per step
        th = pose[0, 2] + 0.01
        pose = pose + [[0.03 * np.cos(th), 0.03 * np.sin(th), 0.02]]
        est = odo.measure(pose, rng)
    return pose, est.copy(), odo


def test_noise_free_odometry_tracks_the_truth():
    pose, est, odo = _drive(OdometryConfig(noise_v=0.0, noise_omega=0.0), 0)
    np.testing.assert_allclose(est[0, :2], pose[0, :2], atol=1e-9)
    assert np.isclose(odo.travelled[0], 200 * 0.03)


def test_noisy_odometry_drifts_and_is_seeded():
    cfg = OdometryConfig(noise_v=0.05, noise_omega=0.05)
    pose, est1, _ = _drive(cfg, 1)
    _, est2, _ = _drive(cfg, 1)
    _, est3, _ = _drive(cfg, 2)
    assert np.array_equal(est1, est2) and not np.array_equal(est1, est3)
    err = np.hypot(*(est1[0, :2] - pose[0, :2]))
    assert 1e-3 < err < 1.0


def test_fix_resets_estimate_and_travel():
    pose, est, odo = _drive(OdometryConfig(), 0, steps=20)
    odo.fix(0, pose[0])
    assert np.array_equal(odo.estimate[0], pose[0]) and odo.travelled[0] == 0.0
