"""The expert's sonar fixes (``expert/sonar_fix.py``) on hand-built situations with known answers:
the belief and its covariance, when a fix counts as fresh, the env's fixes of the robot's own scans,
the gate's edges, and the counts of scans. Written from the mutants mutmut found alive."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sonar_fix_helpers import ODOM, make_fixer, scan_at, step

import parcover_env
from parcover_env.expert.sonar_fix import SCAN_REQUEST, _State
from parcover_env.geometry.poses import compose
from parcover_env.localization.sonar.service import UNINFORMATIVE


def test_the_belief_is_the_odometry_until_a_correction_then_the_correction_composed_with_it():
    fixer = make_fixer()
    odom = np.array([1.0, 0.0, 0.0])
    assert fixer.belief("robot_0", odom) is odom  # never seen: the odometry as it is
    np.testing.assert_array_equal(fixer.covariance("robot_0"), np.zeros((3, 3)))
    cov = np.diag([0.01, 0.02, 0.003])
    fixer.states["robot_0"] = _State(np.array([0.0, 0.0, math.pi / 2]), cov)
    np.testing.assert_allclose(fixer.belief("robot_0", odom), [0.0, 1.0, math.pi / 2], atol=1e-12)
    got = fixer.covariance("robot_0")
    np.testing.assert_array_equal(got, cov)
    got[0, 0] = 5.0  # a copy: the caller cannot change the fixer's covariance
    assert fixer.states["robot_0"].cov[0, 0] == 0.01


def test_a_fix_is_fresh_for_less_than_two_control_steps():
    fixer = make_fixer()
    st = _State(np.array([0.5, 0.0, 0.0]), np.eye(3) * 1e-3, last_odom=ODOM.copy())
    fixer.states["robot_0"] = st
    assert step(fixer, fix_age=0.2, is_leader=False) is None  # two steps old: not fresh, nothing cleared
    np.testing.assert_array_equal(st.correction, [0.5, 0.0, 0.0])
    assert step(fixer, fix_age=0.19, is_leader=False) is None  # fresh: the odometry is absolute again
    np.testing.assert_array_equal(st.correction, np.zeros(3))
    sxy, sth = 0.03, math.radians(2.0)  # the tree's Kinect fix sigmas
    np.testing.assert_allclose(fixer.covariance("robot_0"), np.diag([sxy**2, sxy**2, sth**2]), rtol=1e-12)
    # a fresh fix whose covariance the observation carries takes that one
    observed = np.diag([0.02, 0.03, 0.004])
    step(fixer, fix_age=0.0, odom_cov=observed)
    np.testing.assert_array_equal(fixer.covariance("robot_0"), observed)


def test_the_observed_covariance_is_used_until_a_sonar_fix_then_the_expert_propagates_its_own():
    fixer = make_fixer()
    st = _State(np.zeros(3), np.diag([1e-4, 1e-4, 1e-4]), last_odom=ODOM.copy())
    fixer.states["robot_0"] = st
    observed = np.diag([0.02, 0.03, 0.004])
    step(fixer, odom_cov=observed, is_leader=False)
    np.testing.assert_array_equal(fixer.covariance("robot_0"), observed)
    # corrected by a sonar fix: the observed odometry covariance no longer describes the belief;
    # standing still, the belief's covariance stays as it was
    st.correction = np.array([0.2, 0.0, 0.0])
    st.cov = np.diag([1e-4, 2e-4, 3e-4])
    step(fixer, odom_cov=observed, is_leader=False)
    np.testing.assert_allclose(fixer.covariance("robot_0"), np.diag([1e-4, 2e-4, 3e-4]), atol=1e-15)


def test_the_propagated_covariance_grows_along_the_belief_heading_step_after_step():
    # the correction turns the odometry frame by 90 degrees: a drive along odometry x is a drive
    # along world y, and the along-track variance (two wheels' v |ds| each: v ds / 2) appears there
    fixer = make_fixer()
    v, ds = fixer.odometry.covariance_wheel_variance, 0.01
    assert (fixer.odometry.model, v) == ("wheels", 1e-5)
    st = _State(np.array([0.0, 0.0, math.pi / 2]), np.zeros((3, 3)), last_odom=np.zeros(3))
    fixer.states["robot_0"] = st
    step(fixer, odom=np.array([ds, 0.0, 0.0]), is_leader=False)
    cov = fixer.covariance("robot_0")
    assert cov[1, 1] == pytest.approx(0.5 * v * ds, rel=1e-9)
    # across track only the heading increment's variance (2 v ds / b^2) over half the step
    assert cov[0, 0] == pytest.approx((0.5 * ds) ** 2 * 2 * v * ds / fixer.wheel_base**2, rel=1e-9)
    step(fixer, odom=np.array([2 * ds, 0.0, 0.0]), is_leader=False)  # the next step adds as much again
    assert fixer.covariance("robot_0")[1, 1] == pytest.approx(2 * 0.5 * v * ds, rel=1e-6)


def test_the_env_fix_of_its_own_scan_counts_and_makes_the_robot_drive_on_before_the_next_scan():
    fixer = make_fixer(env_scan=True, rescan_distance=0.5)
    st = _State(np.zeros(3), np.eye(3) * 1e-3, driven_since_scan=0.0, last_odom=ODOM.copy(), missed=True,
                inflation=4.0)
    fixer.states["robot_0"] = st
    assert step(fixer, check=True) == SCAN_REQUEST
    assert step(fixer, scanning=True) == (0.0, 0.0)
    assert step(fixer, fix_age=0.0, scanning=False) is None  # the scan ends with the env's fix
    assert fixer.stats == {"sonar_scans": 1, "sonar_localized": 1, "sonar_failed": 0}
    assert st.scan is None and not st.missed and st.inflation == 1.0
    assert step(fixer, fix_age=0.1) is None  # still fresh the step after: still the fix of its scan
    # stale again: no scan where it stands (not even after the miss before the fix); it drives
    # rescan_distance (0.5 m) first, then brakes for the next scan
    assert step(fixer) is None
    assert step(fixer, speed=4.9) is None  # 0.49 m
    assert step(fixer, speed=1.0) == (0.0, 0.0)  # 0.59 m: due, still rolling
    assert step(fixer) == SCAN_REQUEST
    assert step(fixer, fix_age=0.0) is None  # the env's fix again: counted again
    assert fixer.stats == {"sonar_scans": 2, "sonar_localized": 2, "sonar_failed": 0}
    # a Kinect fix (no scan under way) is not the robot's scan: not counted, and a stale robot
    # may scan at once afterwards
    assert step(fixer, fix_age=0.3) is None
    assert step(fixer, fix_age=0.0) is None
    assert fixer.stats["sonar_localized"] == 2
    assert step(fixer) == SCAN_REQUEST


def test_a_caller_that_passes_no_scanning_entry_ends_the_env_scan():
    fixer = make_fixer(env_scan=True, relocate_distance=0.5)
    st = _State(np.zeros(3), np.eye(3) * 1e-3, driven_since_scan=0.0, last_odom=ODOM.copy())
    fixer.states["robot_0"] = st
    assert step(fixer, check=True) == SCAN_REQUEST
    assert step(fixer) is None  # scanning defaults to 0: the scan is over, without a fix or a result
    assert st.scan is None and st.missed and not st.relocate and fixer.stats["sonar_failed"] == 1


def test_a_fix_resets_the_gate_inflation_and_the_count_of_uninformative_scans():
    fixer = make_fixer()  # its own scans: the gate of the next scan is the fresh covariance, not inflated
    st = _State(np.zeros(3), np.eye(3) * 1e-3, last_odom=ODOM.copy(), missed=True, inflation=4.0)
    fixer.states["robot_0"] = st
    assert step(fixer, fix_age=0.0) is None
    assert step(fixer) == (0.0, fixer.scan_rate)  # after a Kinect fix a stale robot scans at once
    np.testing.assert_allclose(st.scan_cov, fixer.kinect_cov, rtol=1e-12)
    # with the env's scans: one uninformative scan before the fix and one after are not two in a row
    fixer = make_fixer(env_scan=True, relocate_distance=0.5)
    st = _State(np.zeros(3), np.eye(3) * 1e-3, last_odom=ODOM.copy(), uninformative=1)
    fixer.states["robot_0"] = st
    step(fixer, fix_age=0.0)
    assert step(fixer) == SCAN_REQUEST
    assert step(fixer, scanning=False, result=UNINFORMATIVE) is None
    assert st.uninformative == 1 and not fixer.spaced("robot_0") and fixer.relocating("robot_0")


def test_scans_are_counted_one_by_one():
    fixer = make_fixer()
    true = np.array([1.0, 1.0, 0.3])  # a corner of the tree map: the scan localizes exactly
    for k in (1, 2):
        st = _State(np.zeros(3), np.diag([0.01, 0.01, 0.001]), scan_odom=true + [0.1, -0.05, 0.02])
        st.scan, st.scan_cov = scan_at(fixer, true), st.cov.copy()
        fixer._localize(st, np.zeros((0, 2)))
        assert fixer.stats["sonar_localized"] == k and fixer.stats["sonar_failed"] == 0
    st = _State(np.zeros(3), np.diag([0.01, 0.01, 0.001]), scan_odom=true.copy())
    st.scan = type("Scan", (), {"ranges": np.full(fixer.n_bins, fixer.sonar.range_max)})()  # no echo
    for k in (1, 2):
        st.scan_cov = st.cov.copy()
        fixer._localize(st, np.zeros((0, 2)))
        assert fixer.stats == {"sonar_scans": 0, "sonar_localized": 2, "sonar_failed": k}


def test_a_refused_fix_is_remembered_whatever_the_belief_heading():
    # heading 0.5 rad: the fix and the prior agree in heading (their sum, 1 rad, is beyond 40 degrees)
    fixer = make_fixer()
    true = np.array([1.0, 1.0, 0.5])
    odom = true + [0.45, 0.0, 0.0]  # 0.45 m off with a 1 cm covariance: outside the gate
    st = _State(np.zeros(3), np.diag([1e-4, 1e-4, 1e-4]), scan_odom=odom)
    st.scan, st.scan_cov = scan_at(fixer, true), st.cov.copy()
    fixer._localize(st, np.zeros((0, 2)))
    assert not np.any(st.correction) and st.missed
    np.testing.assert_allclose(compose(st.refused, odom), true, atol=1e-3)


def test_the_localizer_searches_headings_within_the_heading_gate():
    # heading sigma 7 degrees: the gate admits 15 + 4 x 7 = 43 -> at most 40 degrees, wider than the
    # localizer's own default (30 degrees); a belief 35 degrees off in heading is fixed
    fixer = make_fixer()
    true = np.array([1.0, 1.0, 0.3])
    st = _State(np.zeros(3), np.diag([0.01, 0.01, math.radians(7.0) ** 2]),
                scan_odom=true + [0.05, -0.05, -math.radians(35.0)])
    st.scan, st.scan_cov = scan_at(fixer, true), st.cov.copy()
    fixer._localize(st, np.zeros((0, 2)))
    np.testing.assert_allclose(compose(st.correction, st.scan_odom), true, atol=1e-3)


def test_a_fix_on_the_edge_of_the_gate_is_inside():
    # gate_distance 1 m over 4 sigmas: a position sigma of 0.25 m with a zero covariance; heading gate 18 deg
    fixer = make_fixer(gate_distance=1.0, gate_sigmas=4.0, gate_heading_deg=18.0)
    prior, cov = np.array([1.0, 1.0, 0.0]), np.zeros((3, 3))
    assert fixer.accept(np.array([2.0, 1.0, 0.0]), prior, cov)  # 4 sigmas exactly
    assert not fixer.accept(np.array([2.0 + 1e-9, 1.0, 0.0]), prior, cov)
    assert fixer.accept(np.array([1.0, 1.0, math.radians(18.0)]), prior, cov)  # 18 degrees exactly
    assert not fixer.accept(np.array([1.0, 1.0, math.radians(18.0) + 1e-9]), prior, cov)


def test_a_confirming_fix_on_the_edge_of_the_confirm_distance_and_heading_confirms():
    fixer = make_fixer(confirm_distance=0.625, gate_heading_deg=18.0)
    refused, odom = np.zeros(3), np.array([1.0, 1.0, 0.0])  # carried: (1, 1, 0)
    assert fixer.confirms(np.array([1.375, 1.5, 0.0]), refused, odom)  # 0.625 m away exactly
    assert not fixer.confirms(np.array([1.375, 1.5 + 1e-9, 0.0]), refused, odom)
    assert fixer.confirms(np.array([1.0, 1.0, math.radians(18.0)]), refused, odom)  # 18 degrees exactly
    assert not fixer.confirms(np.array([1.0, 1.0, math.radians(18.0) + 1e-9]), refused, odom)


def test_without_a_shift_test_every_scan_pins_its_pose_down():
    pose = np.array([1.0, 1.0, 0.3])
    no_echo = np.full(72, 3.0)  # shifted, a scan without echoes matches no worse: it pins nothing down
    assert not make_fixer(shift_test=0.2).pins_down(no_echo, pose, np.zeros((0, 2)))
    assert make_fixer(shift_test=0.0).pins_down(no_echo, pose, np.zeros((0, 2)))


def test_a_pose_measured_relative_to_a_teammate_is_fused_into_the_belief():
    fixer = make_fixer()
    odom = np.array([1.0, 2.0, 0.5])
    fixer.states["robot_0"] = _State(np.zeros(3), np.diag([0.03, 0.01, 0.01]))
    fixer.relative_update("robot_0", odom, odom + [0.4, 0.2, 0.1], np.diag([0.01, 0.03, 0.01]))
    # x: the belief's variance 3x the measurement's -> 3/4 of the way; y: 1/4; heading: half way
    np.testing.assert_allclose(fixer.belief("robot_0", odom), [1.3, 2.05, 0.55], atol=1e-12)
    np.testing.assert_allclose(fixer.covariance("robot_0"), np.diag([0.0075, 0.0075, 0.005]), atol=1e-15)
    assert fixer.corrected("robot_0")
    # a correction: it moves with the odometry (0.1 m further along the odometry heading)
    ahead = odom + [0.1 * math.cos(0.5), 0.1 * math.sin(0.5), 0.0]
    belief = fixer.belief("robot_0", ahead)
    np.testing.assert_allclose(belief[:2] - [1.3, 2.05], 0.1 * np.array([math.cos(0.55), math.sin(0.55)]),
                               atol=1e-12)
    # the next measurement is fused into the corrected belief, not into the odometry pose
    fixer.relative_update("robot_0", odom, np.array([1.3, 2.05, 0.55]), np.diag([0.0075, 0.0075, 0.005]))
    np.testing.assert_allclose(fixer.belief("robot_0", odom), [1.3, 2.05, 0.55], atol=1e-12)
    np.testing.assert_allclose(fixer.covariance("robot_0"), np.diag([0.00375, 0.00375, 0.0025]), atol=1e-15)
    # a robot never seen has an exact (zero) covariance: the measurement leaves it where it is
    fixer.relative_update("robot_1", odom, odom + [0.4, 0.2, 0.1], np.diag([0.01, 0.03, 0.01]))
    np.testing.assert_allclose(fixer.belief("robot_1", odom), odom, atol=1e-12)
    np.testing.assert_allclose(fixer.covariance("robot_1"), np.zeros((3, 3)), atol=1e-15)


def test_the_fixer_takes_its_settings_from_the_scenario_and_the_expert_config():
    from dataclasses import replace

    from parcover_env.expert.config import SonarFixConfig, expert_config
    from parcover_env.expert.sonar_fix import SonarFixer

    scenario = parcover_env.load_scenario("tree")
    fixer = SonarFixer(scenario, np.radians(np.arange(0, 360, 45.0)), 0.1)  # no config: the expert's
    assert fixer.cfg == expert_config(scenario).sonar_fix
    assert fixer.stats == {"sonar_scans": 0, "sonar_localized": 0, "sonar_failed": 0}
    assert fixer.n_bins == 72  # 5-degree bins
    sonar = replace(scenario.robot.sonar, scan_step_deg=1.0)
    one_degree = replace(scenario, robot=replace(scenario.robot, sonar=sonar))
    assert SonarFixer(one_degree, fixer.beams, 0.1).n_bins == 360
    # Kinect fix: 0.03 m and 2 degrees (tree); sonar fix: fix_sigma 0.05 m and 2 degrees
    np.testing.assert_allclose(fixer.kinect_cov, np.diag([0.03**2, 0.03**2, math.radians(2.0) ** 2]), rtol=1e-12)
    np.testing.assert_allclose(fixer.fix_cov, np.diag([0.05**2, 0.05**2, math.radians(2.0) ** 2]), rtol=1e-12)
    np.testing.assert_allclose(make_fixer(fix_sigma=0.1, fix_sigma_heading_deg=3.0).fix_cov,
                               np.diag([0.01, 0.01, math.radians(3.0) ** 2]), rtol=1e-12)
    # the scan turns at scan_rate, at most the robot's max_turn_rate (1.5 rad/s)
    assert fixer.scan_rate == 0.6 and make_fixer(scan_rate=2.0).scan_rate == 1.5
    assert SonarFixConfig().scan_rate == 0.6


def test_a_robot_is_corrected_only_by_a_nonzero_correction():
    fixer = make_fixer()
    assert not fixer.corrected("robot_0")  # never seen
    fixer.states["robot_0"] = _State(np.zeros(3), np.eye(3))
    assert not fixer.corrected("robot_0")
    fixer.states["robot_0"].correction = np.array([0.0, 0.0, 1.0])
    assert fixer.corrected("robot_0") and not fixer.corrected("robot_1")
    fixer.states["robot_0"].correction = np.ones(3)
    assert fixer.corrected("robot_0")


def _arc_expected(p0: np.ndarray, heading: float, ds: float, dth: float, q: np.ndarray) -> np.ndarray:
    """Chong & Kleeman's step of a pose covariance ``p0`` for a mid-heading arc (``F P F^T + G Q G^T``)."""
    c, s = math.cos(heading + 0.5 * dth), math.sin(heading + 0.5 * dth)
    f = np.array([[1.0, 0.0, -ds * s], [0.0, 1.0, ds * c], [0.0, 0.0, 1.0]])
    g = np.array([[c, -0.5 * ds * s], [s, 0.5 * ds * c], [0.0, 1.0]])
    return f @ p0 @ f.T + g @ q @ g.T


# an arc: from heading 0.2 turned by 0.4 rad, 0.1 m along the mid heading 0.4 (odometry frame);
# the belief heading before the step is 1.0 rad
ARC_PREV, ARC_NEW = np.array([1.0, 2.0, 0.2]), np.array([1.0 + 0.1 * math.cos(0.4), 2.0 + 0.1 * math.sin(0.4), 0.6])
P0 = np.array([[1e-4, 2e-5, 1e-5], [2e-5, 2e-4, -1e-5], [1e-5, -1e-5, 3e-4]])


def test_the_belief_covariance_on_an_arc_splits_the_wheels_variances():
    from parcover_env.config import OdometryConfig
    from parcover_env.expert.sonar_fix import belief_covariance_step

    v, b = 1e-5, 0.18
    got = belief_covariance_step(P0, ARC_PREV, ARC_NEW, 1.0, OdometryConfig(covariance_wheel_variance=v), b)
    # ds 0.1 m, dth 0.4 rad: the wheels drive 0.1 -+ 0.4 x 0.18 / 2 = 0.064 and 0.136 m, each with
    # variance v x its distance; ds = mean of the wheels, dth = their difference / b
    left, right = v * 0.064, v * 0.136
    q = np.array([[0.25 * (left + right), 0.5 * (right - left) / b],
                  [0.5 * (right - left) / b, (left + right) / b**2]])
    np.testing.assert_allclose(got, _arc_expected(P0, 1.0, 0.1, 0.4, q), rtol=1e-9, atol=1e-18)


def test_the_belief_covariance_with_the_motion_model_adds_relative_noise_of_ds_and_dth():
    from parcover_env.config import OdometryConfig
    from parcover_env.expert.sonar_fix import belief_covariance_step

    odo = OdometryConfig(model="motion", noise_v=0.02, noise_omega=0.03)
    got = belief_covariance_step(P0, ARC_PREV, ARC_NEW, 1.0, odo, 0.18)
    q = np.diag([(0.02 * 0.1) ** 2, (0.03 * 0.4) ** 2])
    np.testing.assert_allclose(got, _arc_expected(P0, 1.0, 0.1, 0.4, q), rtol=1e-9, atol=1e-18)
    assert got[2, 2] == pytest.approx(3e-4 + 1.44e-4, rel=1e-12)


def test_the_belief_covariance_of_several_robots_is_each_robots_own():
    from parcover_env.config import OdometryConfig
    from parcover_env.expert.sonar_fix import belief_covariance_step

    odo, b = OdometryConfig(covariance_wheel_variance=1e-5), 0.18
    covs, prev = np.stack([P0, 2 * P0]), np.stack([ARC_PREV, np.zeros(3)])
    new, headings = np.stack([ARC_NEW, np.array([0.05, 0.0, -0.1])]), np.array([1.0, -0.3])
    got = belief_covariance_step(covs, prev, new, headings, odo, b)
    assert got.shape == (2, 3, 3)
    for k in range(2):
        np.testing.assert_allclose(got[k], belief_covariance_step(covs[k], prev[k], new[k], headings[k], odo, b),
                                   rtol=1e-12, atol=1e-18)
    assert not np.allclose(got[0], got[1])
