"""Sonar fixes for stale leaders (localization: both): pose algebra, scan binning, end to end."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.config import SonarConfig
from parcover_env.expert.policy import ScriptedExpert
from parcover_env.geometry.poses import compose, inverse
from parcover_env.harness.rollout import run_episode
from parcover_env.localization.sonar.scan import ScanCollector
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.map_model import MapModel


def test_compose_inverse_round_trip():
    a, b = np.array([1.0, -2.0, 0.7]), np.array([0.3, 0.4, -2.0])
    np.testing.assert_allclose(compose(compose(a, b), inverse(b)), a, atol=1e-12)
    np.testing.assert_allclose(compose(inverse(a), a), np.zeros(3), atol=1e-12)


def test_turning_in_place_fills_the_72_bins_like_a_360_scan():
    box = MapModel.from_config(parcover_env.load_scenario("t_room").map)
    ring = SonarRing(SonarConfig(layout="ring", n_beams=16, model="ray"))
    pose = np.array([2.0, 3.0, 0.3])
    reference = ring.scan(pose, box.segments, None, 0.15, None)
    col = ScanCollector(ring.beam_angles, 72, ring.cfg.range_max, start_heading=pose[2], tol_deg=1.0)
    done, heading = False, pose[2]
    while not done:
        ranges = ring.measure(np.array([[*pose[:2], heading]]), box.segments, 0.15, None)[0]
        done = col.add(heading, ranges)
        heading += np.radians(0.5)
    assert np.median(np.abs(col.ranges - reference)) < 0.03


def test_out_of_view_leaders_with_sonar_fixes_succeed_and_localize():
    # the shipped tree is Kinect-only now (its four Kinects see every TP and KPOI, seed A Fig. 6);
    # a generated office has rooms no Kinect sees, where leaders stop for sonar fixes
    env = parcover_env.parallel_env("generated:2")
    assert env.scenario.localization == "both"
    expert = ScriptedExpert.for_env(env)
    m = run_episode(env, expert, 35)
    assert m["success"] and m["sonar_localized"] >= 1 and m["sonar_scans"] >= m["sonar_localized"]


def _fixer(cfg):
    from parcover_env.expert.sonar_fix import SonarFixer

    return SonarFixer(parcover_env.load_scenario("tree"), np.radians(np.arange(0, 360, 45.0)), 0.1, cfg)


def test_fix_gate_is_the_covariance_ellipse_not_a_circle():
    from parcover_env.config import SonarFixConfig

    cfg = SonarFixConfig(gate_distance=0.15, gate_sigmas=4.0, gate_heading_deg=15.0, gate_heading_max_deg=40.0)
    fixer = _fixer(cfg)
    prior = np.array([2.0, 3.0, 0.4])
    # thin along x: sigma 0.3 m along x, 0.01 m along y, heading sigma 3 deg
    cov = np.diag([0.3**2, 0.01**2, np.radians(3.0) ** 2])
    assert fixer.accept(prior + [1.0, 0.0, 0.0], prior, cov)  # 1 m along the major axis: inside
    assert not fixer.accept(prior + [0.0, 1.0, 0.0], prior, cov)  # the same distance across it: out
    assert fixer.accept(prior + [0.0, 0.14, 0.0], prior, cov)  # the floor: gate_distance in any direction
    assert not fixer.accept(prior + [0.0, 0.2, 0.0], prior, cov)
    # the same ellipse turned by 90 degrees swaps the answers
    turned = np.diag([0.01**2, 0.3**2, np.radians(3.0) ** 2])
    assert not fixer.accept(prior + [1.0, 0.0, 0.0], prior, turned)
    assert fixer.accept(prior + [0.0, 1.0, 0.0], prior, turned)
    # heading gate: 15 deg + 4 sigma = 27 deg ...
    assert fixer.accept(prior + [0.0, 0.0, np.radians(26)], prior, cov)
    assert not fixer.accept(prior + [0.0, 0.0, np.radians(-28)], prior, cov)
    # ... at most 40 deg however uncertain the heading: the room turned by 90 or 180 deg stays out
    lost = np.diag([0.3**2, 0.3**2, np.radians(20.0) ** 2])
    assert fixer.accept(prior + [0.0, 0.0, np.radians(39)], prior, lost)
    assert not fixer.accept(prior + [0.0, 0.0, np.radians(42)], prior, lost)
    assert not fixer.accept(prior + [0.0, 0.0, np.pi], prior, lost)


def test_observed_ellipse_entries_invert_to_the_covariance():
    from parcover_env.envs.observations import ellipse_entries
    from parcover_env.expert.sonar_fix import covariance_from_entries

    a = np.radians(30.0)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    cov = np.zeros((3, 3))
    cov[:2, :2] = rot @ np.diag([0.4**2, 0.1**2]) @ rot.T
    cov[2, 2] = 0.05**2
    heading = 1.1
    entries = ellipse_entries(cov[None], np.array([heading]))[0]
    np.testing.assert_allclose(covariance_from_entries(entries, heading), cov, atol=1e-12)


def test_belief_covariance_grows_like_chong_kleeman_on_a_straight_drive():
    from parcover_env.config import OdometryConfig
    from parcover_env.expert.sonar_fix import belief_covariance_step

    odo, b, ds, n = OdometryConfig(covariance_wheel_variance=1e-5), 0.18, 0.01, 200
    cov, pose = np.zeros((3, 3)), np.array([0.0, 0.0, 0.0])
    for _ in range(n):
        nxt = pose + [ds, 0.0, 0.0]
        cov = belief_covariance_step(cov, pose, nxt, 0.0, odo, b)
        pose = nxt
    length, v = n * ds, odo.covariance_wheel_variance
    # along track: the mean of two wheels' variances v|ds| each -> v L / 2
    assert cov[0, 0] == pytest.approx(0.5 * v * length, rel=1e-9)
    # heading: 2 v L / b^2; across track: the heading variance integrated, ~ (2 v / b^2) L^3 / 3
    assert cov[2, 2] == pytest.approx(2 * v * length / b**2, rel=1e-9)
    assert cov[1, 1] == pytest.approx(2 * v / b**2 * length**3 / 3, rel=0.03)
    # the belief heading, not the odometry frame's, orients the growth: turned by 90 deg, x and y swap
    cov90, pose = np.zeros((3, 3)), np.zeros(3)
    for _ in range(n):
        nxt = pose + [ds, 0.0, 0.0]
        cov90 = belief_covariance_step(cov90, pose, nxt, np.pi / 2, odo, b)
        pose = nxt
    assert cov90[1, 1] == pytest.approx(cov[0, 0], rel=1e-6) and cov90[0, 0] == pytest.approx(cov[1, 1], rel=1e-6)


def test_a_refused_fix_is_accepted_when_the_next_scan_confirms_it():
    from parcover_env.config import SonarFixConfig

    fixer = _fixer(SonarFixConfig(confirm_distance=0.2, gate_heading_deg=15.0))
    # a refused fix said: the robot is 1 m further along x than its odometry believes
    refused = compose(np.array([1.0, 0.0, 0.0]), np.zeros(3))
    odom = np.array([3.0, 1.0, 0.5])  # two metres later, by odometry
    carried = compose(refused, odom)
    assert fixer.confirms(carried + [0.1, -0.1, np.radians(5)], refused, odom)
    assert not fixer.confirms(carried + [0.3, 0.0, 0.0], refused, odom)
    assert not fixer.confirms(carried + [0.0, 0.0, np.radians(20)], refused, odom)
    assert not fixer.confirms(carried, None, odom)
