"""Pose accessors, per-step pose error in infos, covariance observations, drive response in the env."""

from __future__ import annotations

import numpy as np

import parcover_env
from parcover_env.envs.observations import ellipse_entries


def _forward(env, steps):
    for _ in range(steps):
        obs, _, _, _, infos = env.step({a: np.array([1.0, 0.1], np.float32) for a in env.agents})
    return obs, infos


def test_accessors_match_the_world_and_the_observations():
    env = parcover_env.parallel_env("office", overrides={"observation": {"pose_source": "odometry"}})
    env.reset(seed=1)
    obs, infos = _forward(env, 15)
    true, est, cov = env.true_poses(), env.pose_estimates(), env.pose_covariances()
    assert true.shape == est.shape == (env.n_robots, 3) and cov.shape == (env.n_robots, 3, 3)
    assert np.array_equal(true, env.world.poses())
    assert np.array_equal(cov, env.odometry.covariance)
    g = env.layout.get
    for i, a in enumerate(env.possible_agents):
        np.testing.assert_allclose([g(obs[a], "x")[0], g(obs[a], "y")[0]], est[i, :2], atol=1e-5)
        assert np.isclose(np.arctan2(g(obs[a], "sin_theta")[0], g(obs[a], "cos_theta")[0]), est[i, 2], atol=1e-5)
        assert np.isclose(infos[a]["pose_error"], np.hypot(*(est[i, :2] - true[i, :2])), rtol=1e-12)
        dth = abs((est[i, 2] - true[i, 2] + np.pi) % (2 * np.pi) - np.pi)
        assert np.isclose(infos[a]["heading_error"], dth, rtol=1e-9, atol=1e-15)
        assert all(np.isscalar(v) or isinstance(v, np.ndarray) for v in infos[a].values())  # flat infos
        np.testing.assert_allclose(obs[a][env.layout.slices["sigma_major"].start:env.layout.slices["sigma_heading"].stop],
                                   ellipse_entries(cov[i:i + 1], est[i:i + 1, 2])[0], rtol=1e-5, atol=1e-7)
    assert all(infos[a]["pose_error"] > 0 for a in env.possible_agents)  # realistic odometry drifts
    est[:] = 0  # a copy: the env's state is untouched
    assert env.pose_estimates().any()


def test_one_step_of_full_forward_from_rest_is_below_90_percent_of_max_speed():
    env = parcover_env.parallel_env("office", overrides={"n_robots": 1})
    env.reset(seed=0)
    obs, _ = _forward(env, 1)
    v_max = env.scenario.robot.max_speed
    wheels = env.world.drive.wheels[0]
    assert wheels.mean() < 0.9 * v_max
    assert 0 < env.layout.get(obs["robot_0"], "v")[0] < 0.9 * v_max  # measured (encoder) speed, not the command


def test_ideal_preset_without_step_noise_has_zero_pose_error():
    env = parcover_env.parallel_env("office", preset="ideal", overrides={
        "observation": {"pose_source": "odometry"}, "robot": {"odometry": {"noise_v": 0.0, "noise_omega": 0.0}}})
    env.reset(seed=2)
    assert env.world.drive is None and "sigma_major" not in env.layout.slices
    for _ in range(10):  # straight: the odometry reproduces the true motion
        obs, _, _, _, infos = env.step({a: np.array([1.0, 0.0], np.float32) for a in env.agents})
        for a in env.possible_agents:
            assert infos[a]["pose_error"] < 1e-12 and infos[a]["heading_error"] < 1e-12
    assert np.array_equal(env.layout.get(obs["robot_0"], "v"), np.float32([env.scenario.robot.max_speed]))


def test_ellipse_entries_of_hand_built_covariances():
    cov = np.zeros((3, 3, 3))
    cov[:, :2, :2] = np.diag([4e-4, 1e-4])  # major axis along world x
    cov[:, 2, 2] = 0.01
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    r = np.array([[c, -s], [s, c]])
    cov[2, :2, :2] = r @ np.diag([4e-4, 1e-4]) @ r.T  # major axis at 30 deg in the world
    e = ellipse_entries(cov, np.array([0.0, np.pi / 2, 0.0]))
    np.testing.assert_allclose(e[:, [0, 1, 4]], [[0.02, 0.01, 0.1]] * 3, rtol=1e-9)
    np.testing.assert_allclose(e[0, 2:4], [1.0, 0.0], atol=1e-12)  # along the robot's x axis
    np.testing.assert_allclose(e[1, 2:4], [-1.0, 0.0], atol=1e-12)  # robot faces +y: axis is across it
    np.testing.assert_allclose(e[2, 2:4], [np.cos(np.pi / 3), np.sin(np.pi / 3)], atol=1e-12)
    circle = ellipse_entries(np.diag([1e-4, 1e-4, 0.0])[None], np.array([1.0]))
    np.testing.assert_allclose(circle[0], [0.01, 0.01, 1.0, 0.0, 0.0], atol=1e-12)


def test_kinect_fix_resets_the_covariance_to_the_fix_covariance():
    env = parcover_env.parallel_env("office")
    env.reset(seed=0)
    s = env.scenario.observation
    for _ in range(60):
        _forward(env, 1)
        fresh = np.flatnonzero(env.fix_age == 0.0)
        if len(fresh):
            i = fresh[0]
            expected = np.diag([s.fix_sigma_xy**2, s.fix_sigma_xy**2, np.radians(s.fix_sigma_heading_deg) ** 2])
            np.testing.assert_allclose(env.pose_covariances()[i], expected, rtol=1e-12)
            return
    raise AssertionError("no Kinect fix in 60 steps of office")
