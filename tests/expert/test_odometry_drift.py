"""The expert's heading drift calibration (expert/odometry_drift.py): a hand-built straight drive with a known
drift per metre, the Kalman update by hand, the calibrated heading by value (issue 42: generated:77, 7018)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import OdometryConfig
from parcover_env.expert.odometry_drift import DriftCalibration

KAPPA = -0.02
"""The odometry's heading drift of the hand-built drive (rad/m; E_d - 1 = 0.0036 on a 0.18 m wheel base)."""


def _drive(cal: DriftCalibration, start: np.ndarray, metres: float, step: float = 0.1) -> np.ndarray:
    """Feed ``cal`` (robot 0) the odometry poses of a straight drive of ``metres`` whose odometry heading
    drifts by KAPPA per metre (the robot truly drives straight along its start heading); returns the last
    calibrated pose."""
    raw = start.astype(float).copy()
    out = cal.step(0, raw, False, 0.0)
    for _ in range(int(round(metres / step))):
        mid = raw[2] + 0.5 * KAPPA * step
        raw = raw + np.array([step * math.cos(mid), step * math.sin(mid), KAPPA * step])
        out = cal.step(0, raw, False, 0.0)
    return out


def test_the_prior_is_the_odometry_error_model():
    cfg = OdometryConfig()
    cal = DriftCalibration(3, cfg, 0.18)
    np.testing.assert_allclose(cal.prior, np.diag([(0.002 / 0.18) ** 2, 0.01**2]))
    assert cal.walk == pytest.approx(2 * 1e-6 / 0.18**2)
    np.testing.assert_array_equal(cal.mean, 0.0)
    with pytest.raises(ValueError, match="wheel_base"):
        DriftCalibration(1, cfg, 0.0)


def test_a_fix_after_a_straight_drive_measures_the_drift_per_metre():
    cal = DriftCalibration(1, OdometryConfig(), 0.18)
    last = _drive(cal, np.zeros(3), 10.0)
    # no estimate yet: the calibrated pose is the odometry's
    np.testing.assert_allclose(last[2], 10.0 * KAPPA, atol=1e-12)
    d, t, driven = cal.since[0]
    assert d == pytest.approx(10.0, abs=1e-9) and t == pytest.approx(-0.2, abs=1e-12) and driven == pytest.approx(10.0)
    fix_var = math.radians(2.0) ** 2
    cal.step(0, np.array([10.0, 0.0, 0.0]), True, fix_var)  # the fix: the robot truly heads along x
    # the Kalman update by hand: e = -0.2 rad = kappa D + beta T, noise fix_var + walk * 10 m
    h, p = np.array([d, t]), cal.prior
    s = h @ p @ h + fix_var + cal.walk * 10.0
    want = p @ h / s * (-0.2)
    np.testing.assert_allclose(cal.mean[0], want, rtol=1e-9)
    assert -0.02 < cal.mean[0, 0] < -0.017  # most of the drift, shrunk a little toward the prior's 0
    # the odometry restarted at the fix: so does the calibrated pose
    np.testing.assert_array_equal(cal.cal[0], [10.0, 0.0, 0.0])
    np.testing.assert_array_equal(cal.since[0], 0.0)
    assert cal.reset_var[0] == fix_var


def test_the_calibrated_heading_removes_the_estimated_drift():
    cal = DriftCalibration(1, OdometryConfig(), 0.18)
    _drive(cal, np.zeros(3), 10.0)
    cal.step(0, np.array([10.0, 0.0, 0.0]), True, math.radians(2.0) ** 2)
    kappa, beta = cal.mean[0]
    last = _drive(cal, np.array([10.0, 0.0, 0.0]), 10.0)
    d, t, _ = cal.since[0]
    raw_heading = 10.0 * KAPPA
    assert last[2] == pytest.approx(raw_heading - kappa * d - beta * t, abs=1e-12)
    assert abs(last[2]) < 0.15 * abs(raw_heading)  # -0.2 rad of drift down to under 0.03 rad
    # a second fix adds a second measurement: nearer the drift still
    cal.step(0, np.array([20.0, 0.0, 0.0]), True, math.radians(2.0) ** 2)
    assert abs(cal.mean[0, 0] - KAPPA) < abs(kappa - KAPPA)


def test_a_chained_heading_is_a_measurement_once_per_spacing():
    cal = DriftCalibration(1, OdometryConfig(), 0.18, spacing=2.0)
    _drive(cal, np.zeros(3), 1.9)
    assert not cal.due(0)
    _drive(cal, cal.raw[0].copy(), 0.2)
    assert cal.due(0)
    d, t, _ = cal.since[0]
    assert d == pytest.approx(2.1, abs=1e-9) and t == pytest.approx(2.1 * KAPPA, abs=1e-12)
    ref_var = math.radians(1.0) ** 2
    cal.measure(0, float(cal.raw[0, 2]), 0.0, ref_var)  # the chained heading: the true one, 1 deg std
    h, p = np.array([d, t]), cal.prior
    want = p @ h / (h @ p @ h + ref_var + cal.walk * 2.1) * (2.1 * KAPPA)
    np.testing.assert_allclose(cal.mean[0], want, rtol=1e-9)
    assert KAPPA < cal.mean[0, 0] < 0.5 * KAPPA  # 2 m against a 1 deg reference: half the drift or more
    assert not cal.due(0)
    # the odometry was not reset (a chained heading is no fix): distance and turn keep adding up
    _drive(cal, cal.raw[0].copy(), 1.0)
    assert cal.since[0, 0] == pytest.approx(3.1, abs=1e-9)


def test_the_expert_calibrates_only_the_wheels_odometry_on_sonar_maps():
    from dataclasses import replace

    import parcover_env
    from parcover_env.expert import expert_for
    from parcover_env.expert.config import expert_config
    from parcover_env.expert.scripted import ScriptedExpert

    env = parcover_env.parallel_env("generated:3")
    obs, _ = env.reset(seed=3)
    expert = expert_for(env)
    expert.reset(obs)
    assert expert.drift is not None and len(expert.drift.mean) == env.mission.n_robots
    expert.act(obs)  # the first step: the calibrated poses are the observed ones
    np.testing.assert_allclose(expert._last_odom, expert._raw)
    cfg = expert_config(env.scenario)
    off = ScriptedExpert.for_env(env, config=replace(cfg, sonar_fix=replace(cfg.sonar_fix, calibrate_drift=False)))
    off.reset(obs)
    assert off.drift is None
    ideal = parcover_env.parallel_env("generated:3", preset="ideal")  # the motion odometry: nothing to calibrate
    obs, _ = ideal.reset(seed=3)
    expert = expert_for(ideal)
    expert.reset(obs)
    assert expert.drift is None


def test_without_an_estimate_the_calibrated_pose_is_the_odometry_pose_along_a_curve():
    cal = DriftCalibration(3, OdometryConfig(), 0.18)
    assert cal.cov.shape == (3, 2, 2)
    raw = np.array([1.0, 2.0, 0.3])
    cal.step(1, raw, False, 0.7)
    assert cal.reset_var[1] == 0.0  # the episode's start is no fix: its heading error is 0
    for _ in range(30):  # an arc: 0.05 m and 0.04 rad per step
        mid = raw[2] + 0.02
        raw = raw + np.array([0.05 * math.cos(mid), 0.05 * math.sin(mid), 0.04])
        out = cal.step(1, raw, False, 0.0)
    np.testing.assert_allclose(out, raw, atol=1e-12)
    np.testing.assert_allclose(cal.since[1], [1.5, 1.2, 1.5], atol=1e-9)


def test_the_calibrated_position_follows_the_calibrated_heading():
    cal = DriftCalibration(1, OdometryConfig(), 0.18)
    cal.mean[0] = [0.1, 0.0]  # 0.1 rad/m believed drift: each 0.1 m step turns the calibrated heading by -0.01 rad
    raw = np.zeros(3)
    cal.step(0, raw, False, 0.0)
    want = np.zeros(3)
    for _ in range(5):
        raw = raw + np.array([0.1, 0.0, 0.0])  # the odometry: straight along x
        out = cal.step(0, raw, False, 0.0)
        mid = want[2] - 0.005
        want = want + np.array([0.1 * math.cos(mid), 0.1 * math.sin(mid), -0.01])
    np.testing.assert_allclose(out, want, atol=1e-12)
    assert out[1] < -0.005  # curving right of the odometry's straight line


def test_measurements_by_hand_with_a_turned_reference_and_a_second_fix():
    cfg = OdometryConfig()
    cal = DriftCalibration(1, cfg, 0.18)
    start = np.array([0.0, 0.0, math.pi / 2])  # heading north: the reference is not 0
    _drive(cal, start, 0.5)
    d, t, driven = cal.since[0]
    assert driven == pytest.approx(0.5)
    v1 = math.radians(2.0) ** 2
    truth = math.pi / 2
    cal.step(0, np.array([0.0, 0.5, truth]), True, v1)  # a fix after 0.5 m: still a measurement
    h, p = np.array([d, t]), cal.prior
    e = 0.5 * KAPPA
    s = h @ p @ h + v1 + cal.walk * 0.5
    gain = p @ h / s
    np.testing.assert_allclose(cal.mean[0], gain * e, rtol=1e-9, atol=1e-15)
    p1 = p - np.outer(gain, h @ p)
    np.testing.assert_allclose(cal.cov[0], p1, rtol=1e-9)
    # a second fix: the first fix's heading variance counts as the error at the reset
    _drive(cal, np.array([0.0, 0.5, truth]), 3.0)
    d, t, _ = cal.since[0]
    v2 = math.radians(1.0) ** 2
    m1 = cal.mean[0].copy()
    cal.step(0, np.array([0.0, 3.5, truth]), True, v2)
    h = np.array([d, t])
    s = h @ p1 @ h + v2 + v1 + cal.walk * 3.0
    gain = p1 @ h / s
    np.testing.assert_allclose(cal.mean[0], m1 + gain * (3.0 * KAPPA - h @ m1), rtol=1e-9)
    assert cal.reset_var[0] == v2


def test_nothing_measured_without_a_drive_and_spacing_checked():
    cal = DriftCalibration(1, OdometryConfig(), 0.18)
    cal.step(0, np.zeros(3), False, 0.0)
    cal.measure(0, 0.3, 0.0, 0.0)  # no distance, no turn, no variance: no information, no NaN
    np.testing.assert_array_equal(cal.mean[0], 0.0)
    cal.step(0, np.zeros(3), True, 0.0)  # a fix before any drive: no measurement either
    np.testing.assert_array_equal(cal.mean[0], 0.0)
    cal.unmeasured[0] = 2.0
    assert cal.due(0)
    cal.measure(0, 0.0, 0.0, 1e-4)
    _drive(cal, cal.raw[0].copy(), 1.5)
    assert not cal.due(0)  # counted again from 0 after the measurement
    _drive(cal, cal.raw[0].copy(), 0.5)
    assert cal.due(0)
    assert DriftCalibration(1, OdometryConfig(), 0.18, spacing=0.5).spacing == 0.5
    with pytest.raises(ValueError, match="spacing"):
        DriftCalibration(1, OdometryConfig(), 0.18, spacing=0.0)
