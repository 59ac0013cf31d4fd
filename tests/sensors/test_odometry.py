"""Odometry: exact without noise, drifting with it, deterministic per seed."""

from __future__ import annotations

import numpy as np
from references import onboard as reference

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


# ---------------------------------------------------------------- wheel encoder model (issue 13)
import pytest  # noqa: E402

from parcover_env.sensors.odometry import (  # noqa: E402
    encoder_factors,
    integrate,
    propagate_covariance,
    wheel_increment_cov,
)

B = 0.18
QUIET = OdometryConfig(diameter_ratio_std=0.0, scale_std=0.0, wheelbase_std=0.0, wheel_variance=0.0,
                       slip_accel=0.0, slip_turn=0.0, covariance_wheel_variance=0.0)


def _wheels(cfg, travel, steps, e_d=1.0, scale=1.0, e_b=1.0, change=None, seed=0):
    odo = Odometry(cfg, np.zeros((len(travel), 3)), B)
    odo.set_systematic(e_d, scale, e_b)
    rng = np.random.default_rng(seed)
    change = np.zeros_like(travel) if change is None else change
    for _ in range(steps):
        odo.measure_wheels(travel, change, 0.1, rng)
    return odo


def test_encoder_factors_follow_the_diameter_ratio():
    # D_L = 2 D_n / (E_d + 1), D_R = 2 E_d D_n / (E_d + 1); a reading is distance x D_n / D
    np.testing.assert_allclose(encoder_factors(1.01, 1.0), [2.01 / 2, 2.01 / 2.02], rtol=1e-15)
    np.testing.assert_allclose(encoder_factors(1.0, 1.02), [1 / 1.02, 1 / 1.02], rtol=1e-15)


def test_without_errors_the_wheel_odometry_is_exact():
    odo = _wheels(QUIET, np.array([[0.01, 0.02]]), 50)
    # constant arc: ds = 0.015, dtheta = 0.01 / 0.18 per step
    dth = 0.01 / B
    th = np.arange(50) * dth + 0.5 * dth
    np.testing.assert_allclose(odo.estimate[0], [np.sum(0.015 * np.cos(th)), np.sum(0.015 * np.sin(th)), 50 * dth],
                               atol=1e-12)
    assert not odo.covariance.any()


def test_straight_drive_with_larger_right_wheel_is_believed_to_curve_clockwise():
    e_d, s = 1.01, 2.0  # 100 steps of 0.02 m on both wheels (the true motion is straight)
    odo = _wheels(QUIET, np.array([[0.02, 0.02]]), 100, e_d=e_d)
    expected = s * (e_d + 1) / 2 * (1 / e_d - 1) / B  # UMBmark: (d_R - d_L) / b, readings x D_n / D
    assert expected < 0
    assert np.isclose(odo.estimate[0, 2], expected, rtol=1e-9)
    assert odo.estimate[0, 1] < 0  # the estimate drifts right: the robot is really left of it
    odo_small = _wheels(QUIET, np.array([[0.02, 0.02]]), 100, e_d=1 / e_d)
    assert np.isclose(odo_small.estimate[0, 2], -expected, rtol=1e-9)  # mirror: counter-clockwise


def test_wheelbase_error_scales_a_pure_turn():
    travel = np.array([[-0.009, 0.009]])  # 0.1 rad per step in place
    for e_b in (0.98, 1.0, 1.03):
        odo = _wheels(QUIET, travel, 10, e_b=e_b)
        assert np.isclose(odo.estimate[0, 2], e_b * 1.0, rtol=1e-12)
        assert np.allclose(odo.estimate[0, :2], 0.0, atol=1e-15)


def test_scale_error_shortens_the_believed_distance():
    odo = _wheels(QUIET, np.array([[0.02, 0.02]]), 100, scale=1.02)
    assert np.isclose(odo.estimate[0, 0], 2.0 / 1.02, rtol=1e-12) and odo.estimate[0, 2] == 0.0


def test_slip_makes_encoders_over_read_in_proportion_to_acceleration_and_turn_rate():
    cfg = OdometryConfig(diameter_ratio_std=0.0, scale_std=0.0, wheelbase_std=0.0, wheel_variance=0.0,
                         slip_accel=0.1, slip_turn=0.05, covariance_wheel_variance=0.0)
    travel, change = np.array([[0.01, 0.028]]), np.array([[0.1, 0.2]])  # mean |a| 1 and 2 m/s^2 over 0.1 s
    odo = _wheels(cfg, travel, 1, change=change, seed=7)
    z = np.abs(np.random.default_rng(7).standard_normal((2, 1, 2))[0, 0])
    rate = 0.018 / (B * 0.1)  # true turn rate (rad/s)
    read = travel[0] * (1 + z * (0.1 * np.array([1.0, 2.0]) + 0.05 * rate))
    assert np.all(read > travel[0])
    dth = (read[1] - read[0]) / B
    np.testing.assert_allclose(odo.estimate[0], [read.mean() * np.cos(dth / 2), read.mean() * np.sin(dth / 2), dth],
                               rtol=1e-12)


def test_random_wheel_error_variance_grows_with_distance():
    cfg = OdometryConfig(diameter_ratio_std=0.0, scale_std=0.0, wheelbase_std=0.0, wheel_variance=1e-4,
                         slip_accel=0.0, slip_turn=0.0)
    n = 4000
    odo = _wheels(cfg, np.full((n, 2), 0.01), 100, seed=3)  # 1 m per wheel
    # heading variance: 2 k s / b^2 (independent wheels), distance variance k s / 2
    assert np.isclose(np.var(odo.estimate[:, 2]), 2 * 1e-4 * 1.0 / B**2, rtol=0.1)
    assert np.isclose(np.mean(odo.estimate[:, 0]), 1.0, atol=2e-3)


def test_covariance_of_a_straight_line_matches_the_closed_form():
    k, d, n = 1e-5, 0.01, 200
    cfg = OdometryConfig(diameter_ratio_std=0.0, scale_std=0.0, wheelbase_std=0.0, wheel_variance=0.0,
                         slip_accel=0.0, slip_turn=0.0, covariance_wheel_variance=k)
    odo = _wheels(cfg, np.array([[d, d]]), n)
    s = n * d
    p = odo.covariance[0]
    # Chong & Kleeman, straight line: P_xx = k s / 2, P_thth = 2 k s / b^2, P_y,th = k s^2 / b^2,
    # P_yy = 2 k s^3 / (3 b^2) (continuous limit; the discrete update adds - k s d^2 / (6 b^2))
    assert np.isclose(p[0, 0], k * s / 2, rtol=1e-12)
    assert np.isclose(p[2, 2], 2 * k * s / B**2, rtol=1e-12)
    assert np.isclose(p[1, 2], k * s**2 / B**2, rtol=1e-12)
    assert np.isclose(p[1, 1], 2 * k * s**3 / (3 * B**2) - k * s * d**2 / (6 * B**2), rtol=1e-12)
    assert np.isclose(p[1, 1], 2 * k * s**3 / (3 * B**2), rtol=1e-4)
    assert p[0, 1] == 0.0 and p[0, 2] == 0.0


def test_covariance_step_rotates_with_the_heading():
    q = wheel_increment_cov(np.array([1e-4]), np.array([4e-4]), B)
    np.testing.assert_allclose(q[0], [[1.25e-4, 1.5e-4 / B / 1], [1.5e-4 / B, 5e-4 / B**2]], rtol=1e-12)
    p0 = np.zeros((1, 3, 3))
    east = propagate_covariance(p0, np.array([0.0]), np.array([0.1]), np.array([0.0]), q)[0]
    north = propagate_covariance(p0, np.array([np.pi / 2]), np.array([0.1]), np.array([0.0]), q)[0]
    assert np.isclose(north[1, 1], east[0, 0]) and np.isclose(north[0, 0], east[1, 1], atol=1e-20)
    assert np.isclose(east[1, 2], 0.05 * q[0, 1, 1]) and np.isclose(east[0, 2], q[0, 0, 1])


def test_fix_sets_the_fix_covariance():
    odo = _wheels(OdometryConfig(), np.array([[0.02, 0.02]]), 20)
    assert odo.covariance[0, 1, 1] > 0
    cov = np.diag([9e-4, 9e-4, 1e-3])
    odo.fix(0, [1.0, 2.0, 0.5], cov)
    assert np.array_equal(odo.covariance[0], cov) and np.array_equal(odo.estimate[0], [1.0, 2.0, 0.5])


def test_systematic_errors_are_drawn_per_robot_from_the_episode_rng():
    cfg = OdometryConfig()
    a = Odometry(cfg, np.zeros((3, 3)), B, np.random.default_rng(5))
    b = Odometry(cfg, np.zeros((3, 3)), B, np.random.default_rng(5))
    z = np.random.default_rng(5).standard_normal((3, 3))
    np.testing.assert_allclose(a.e_d, 1 + cfg.diameter_ratio_std * z[0], rtol=1e-15)
    np.testing.assert_allclose(a.scale, 1 + cfg.scale_std * z[1], rtol=1e-15)
    np.testing.assert_allclose(a.e_b, 1 + cfg.wheelbase_std * z[2], rtol=1e-15)
    assert np.array_equal(a.e_d, b.e_d) and len(set(a.e_d)) == 3
    assert np.allclose(a.believed_base, B / a.e_b)
    ideal = Odometry(OdometryConfig(model="motion"), np.zeros((3, 3)), B, np.random.default_rng(5))
    assert np.all(ideal.e_d == 1.0) and np.all(ideal.factors == 1.0)


def test_motion_model_step_and_its_covariance_by_hand():
    cfg = OdometryConfig(model="motion", noise_v=0.1, noise_omega=0.2)
    start = np.array([[0.0, 0.0, 0.3], [1.0, 1.0, -0.2]])
    odo = Odometry(cfg, start, B)
    true = start + [[0.05 * np.cos(0.35), 0.05 * np.sin(0.35), 0.1], [0.0, 0.0, -0.4]]
    est = odo.measure(true, np.random.default_rng(4)).copy()
    z = np.random.default_rng(4).standard_normal(2), np.random.default_rng(4).standard_normal(4)[2:]
    ds_m = np.array([0.05, 0.0]) * (1 + 0.1 * z[0])
    dth_m = np.array([0.1, -0.4]) * (1 + 0.2 * z[1])
    mid = start[:, 2] + dth_m / 2
    np.testing.assert_allclose(est[:, 0], start[:, 0] + ds_m * np.cos(mid), atol=1e-15)
    np.testing.assert_allclose(est[:, 2], start[:, 2] + dth_m, atol=1e-15)
    q = np.zeros((2, 2, 2))
    q[:, 0, 0], q[:, 1, 1] = (0.1 * ds_m) ** 2, (0.2 * dth_m) ** 2
    np.testing.assert_allclose(odo.covariance, propagate_covariance(np.zeros((2, 3, 3)), start[:, 2], ds_m, dth_m, q),
                               rtol=1e-12, atol=1e-20)
    assert odo.covariance[1, 2, 2] == pytest.approx((0.2 * dth_m[1]) ** 2, rel=1e-12)
    np.testing.assert_allclose(odo.travelled, np.abs(ds_m)) and np.testing.assert_allclose(odo.turned, np.abs(dth_m))


def _pose_step(p, u):
    out = np.array(p, dtype=float)[None].copy()
    integrate(out, np.array([u[0]]), np.array([u[1]]))
    return out[0]


def test_covariance_jacobians_match_finite_differences():
    theta, ds, dth = 0.7, 0.05, 0.3
    p0 = np.array([0.3, -0.2, theta])
    a = np.array([[2.0, 0.3, 0.1], [0.3, 1.0, -0.2], [0.1, -0.2, 0.5]]) * 1e-4
    q = np.array([[[3e-6, 1e-6], [1e-6, 5e-5]]])
    eps = 1e-7
    f = np.stack([(_pose_step(p0 + eps * e, (ds, dth)) - _pose_step(p0 - eps * e, (ds, dth))) / (2 * eps)
                  for e in np.eye(3)], axis=1)
    g = np.stack([(_pose_step(p0, (ds, dth) + eps * e) - _pose_step(p0, (ds, dth) - eps * e)) / (2 * eps)
                  for e in np.eye(2)], axis=1)
    got = propagate_covariance(a[None], np.array([theta]), np.array([ds]), np.array([dth]), q)[0]
    np.testing.assert_allclose(got, f @ a @ f.T + g @ q[0] @ g.T, rtol=1e-6, atol=1e-14)


def test_random_wheel_error_is_drawn_exactly_and_the_arc_covariance_uses_each_wheel():
    k, kc = 4e-6, 2e-5
    cfg = OdometryConfig(diameter_ratio_std=0.0, scale_std=0.0, wheelbase_std=0.0, wheel_variance=k,
                         slip_accel=0.0, slip_turn=0.0, covariance_wheel_variance=kc)
    travel = np.array([[0.01, 0.03], [0.02, -0.02]])
    rng = np.random.default_rng(11)
    odo = _wheels(cfg, travel, 1, seed=11)
    z = rng.standard_normal((2, 2, 2))
    read = travel + np.sqrt(k * np.abs(travel)) * z[1]
    ds, dth = read.mean(axis=1), (read[:, 1] - read[:, 0]) / B
    np.testing.assert_allclose(odo.estimate[:, 2], dth, rtol=1e-12)
    np.testing.assert_allclose(odo.estimate[:, 0], ds * np.cos(dth / 2), rtol=1e-12)
    q = wheel_increment_cov(kc * np.abs(read[:, 0]), kc * np.abs(read[:, 1]), B)
    np.testing.assert_allclose(odo.covariance, propagate_covariance(np.zeros((2, 3, 3)), np.zeros(2), ds, dth, q),
                               rtol=1e-12)
    assert q[0, 0, 1] > 0  # the faster right wheel is the noisier: heading and distance errors correlate
    odo_rng = np.random.default_rng(11)
    Odometry(cfg, np.zeros((2, 3)), B).measure_wheels(travel, np.zeros_like(travel), 0.1, odo_rng)
    assert odo_rng.standard_normal() == np.random.default_rng(11).standard_normal(9)[8]  # 2 x 2 wheels x 2 robots


def test_integer_start_poses_give_float_estimates():
    for model in ("wheels", "motion"):
        odo = Odometry(OdometryConfig(model=model, noise_v=0.0, noise_omega=0.0), [[0, 0, 0]], B)
        odo.measure_wheels(np.array([[0.01, 0.01]]), np.zeros((1, 2)), 0.1, np.random.default_rng(0))
        odo.measure(np.array([[0.5, 0.0, 0.0]]), np.random.default_rng(0))
        assert odo.estimate.dtype == float and odo._last_true.dtype == float
        assert np.isclose(odo.estimate[0, 0], 0.51, atol=1e-3)  # 0.01 m on the wheels, then 0.5 m of motion


def test_wheel_odometry_accumulates_distance_and_turn_until_a_fix():
    odo = _wheels(QUIET, np.array([[0.02, 0.002]]), 3)  # clockwise arc
    assert np.isclose(odo.travelled[0], 3 * 0.011) and np.isclose(odo.turned[0], 3 * 0.018 / B)
    assert odo.estimate[0, 2] < 0
    odo.covariance[:] = 1.0
    odo.fix(0, [0.0, 0.0, 0.0])
    assert not odo.covariance.any() and odo.travelled[0] == 0.0 and odo.turned[0] == 0.0


def test_systematic_draws_use_three_normals_per_robot():
    rng = np.random.default_rng(9)
    Odometry(OdometryConfig(), np.zeros((2, 3)), B, rng)
    assert rng.standard_normal() == np.random.default_rng(9).standard_normal(7)[6]


def test_compiled_wheel_step_equals_the_numpy_formulas():
    cfg = OdometryConfig(model="wheels", diameter_ratio_std=0.01, scale_std=0.01, wheelbase_std=0.02)
    g = np.random.default_rng(0)
    poses = np.column_stack([g.uniform(0, 5, (6, 2)), g.uniform(-3, 3, 6)])
    odo = Odometry(cfg, poses, 0.18, np.random.default_rng(1))
    for step in range(30):
        travel = g.uniform(-0.05, 0.06, (6, 2))
        change = g.uniform(0, 0.4, (6, 2))
        a, b = np.random.default_rng(step), np.random.default_rng(step)
        want = reference.wheel_odometry(odo, travel, change, 0.1, b)
        odo.measure_wheels(travel, change, 0.1, a)
        for got, ref in zip((odo.estimate, odo.covariance, odo.travelled, odo.turned), want, strict=True):
            np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-15)
        assert a.random() == b.random()  # the same draws
    assert odo.covariance[:, 0, 0].min() > 0 and np.allclose(odo.covariance, odo.covariance.transpose(0, 2, 1))
