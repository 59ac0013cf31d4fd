"""Sonar fixes for stale leaders (localization: both): pose algebra, scan binning, end to end."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.config import SonarConfig
from parcover_env.expert import expert_for
from parcover_env.expert.scripted import ScriptedExpert
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
    expert = expert_for(env)
    m = run_episode(env, expert, 35)
    assert m["success"] and m["sonar_localized"] >= 1 and m["sonar_scans"] >= m["sonar_localized"]


def _fixer(cfg):
    from parcover_env.expert.sonar_fix import SonarFixer

    return SonarFixer(parcover_env.load_scenario("tree"), np.radians(np.arange(0, 360, 45.0)), 0.1, cfg)


def test_fix_gate_is_the_covariance_ellipse_not_a_circle():
    from parcover_env.expert.config import SonarFixConfig

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
    from parcover_env.expert.config import SonarFixConfig

    fixer = _fixer(SonarFixConfig(confirm_distance=0.2, gate_heading_deg=15.0))
    # a refused fix said: the robot is 1 m further along x than its odometry believes
    refused = compose(np.array([1.0, 0.0, 0.0]), np.zeros(3))
    odom = np.array([3.0, 1.0, 0.5])  # two metres later, by odometry
    carried = compose(refused, odom)
    assert fixer.confirms(carried + [0.1, -0.1, np.radians(5)], refused, odom)
    assert not fixer.confirms(carried + [0.3, 0.0, 0.0], refused, odom)
    assert not fixer.confirms(carried + [0.0, 0.0, np.radians(20)], refused, odom)
    assert not fixer.confirms(carried, None, odom)


def test_chain_pose_places_the_follower_behind_the_robot_ahead_with_the_camera_noise():
    from parcover_env.expert.sonar_fix import chain_pose

    # robot ahead at (2, 1) facing +y; the follower sees it 0.5 m straight ahead, same heading
    ahead, rel = np.array([2.0, 1.0, np.pi / 2]), np.array([0.5, 0.0, 0.0])
    pose, cov = chain_pose(ahead, np.zeros((3, 3)), rel, range_noise=0.02, bearing_noise=0.01, heading_noise=0.03)
    np.testing.assert_allclose(pose, [2.0, 0.5, np.pi / 2], atol=1e-12)
    var = 0.25 * (0.02**2 + 0.01**2 + 0.03**2)
    np.testing.assert_allclose(cov, np.diag([var, var, 0.03**2]), atol=1e-15)
    # a heading uncertainty ahead swings the follower sideways (across the 0.5 m offset), not along it
    _, cov = chain_pose(ahead, np.diag([0.0, 0.0, 0.1**2]), rel, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(cov[:2, :2], [[(0.5 * 0.1) ** 2, 0.0], [0.0, 0.0]], atol=1e-15)
    assert cov[0, 2] == pytest.approx(0.5 * 0.1**2)
    assert cov[2, 2] == pytest.approx(0.1**2)


def test_fuse_pose_weights_by_the_covariances_and_wraps_the_heading():
    from parcover_env.expert.sonar_fix import fuse_pose

    prior, meas = np.array([0.0, 0.0, np.pi - 0.1]), np.array([1.0, 2.0, -np.pi + 0.1])
    pose, cov = fuse_pose(prior, np.diag([0.03, 0.01, 0.01]), meas, np.diag([0.01, 0.03, 0.01]))
    # x: prior var 3x the measurement's -> 3/4 of the way; y: 1/4; heading: half way across +-pi
    np.testing.assert_allclose(pose, [0.75, 0.5, np.pi], atol=1e-12)
    np.testing.assert_allclose(cov, np.diag([0.0075, 0.0075, 0.005]), atol=1e-15)
    # an exact prior ignores the measurement
    pose, _ = fuse_pose(prior, np.zeros((3, 3)), meas, np.zeros((3, 3)))
    np.testing.assert_allclose(pose, prior)


def test_a_follower_that_sees_its_leader_shares_the_leaders_accuracy():
    # generated:59: robot_1 follows robot_0 for ~60 s through turns and contacts. With the camera
    # chain its belief is never much worse than its leader's; on odometry alone it drifts ~0.5 m
    env = parcover_env.parallel_env("generated:59")
    excess = {}
    for chain in (True, False):
        expert = ScriptedExpert.for_env(env, config=_expert_cfg(env, follow_chain=chain))
        obs, _ = env.reset(seed=59)
        expert.reset(obs)
        worst = 0.0
        for _ in range(450):
            obs, *_ = env.step(expert.act(obs))
            if obs["robot_1"][env.layout.slices["leader"]][0] < 0.5:
                err = np.hypot(*(expert.belief()[:2, :2] - env.true_poses()[:2, :2]).T)
                worst = max(worst, float(err[1] - err[0]))
        excess[chain] = worst
    assert excess[True] < 0.2 < 0.35 < excess[False], excess


def _expert_cfg(env, **sonar_fix):
    from dataclasses import replace

    from parcover_env.expert.config import expert_config

    cfg = expert_config(env.scenario)
    return replace(cfg, sonar_fix=replace(cfg.sonar_fix, **sonar_fix))


def test_a_refused_fix_starts_the_next_scan_at_once_up_to_refused_rescans():
    from parcover_env.expert.config import SonarFixConfig
    from parcover_env.expert.sonar_fix import _State

    fixer = _fixer(SonarFixConfig(refused_rescans=2, rescan_distance=2.0))
    odom, ranges = np.array([1.0, 1.0, 0.0]), np.full(len(fixer.beams), 1.0)

    def starts_scan(state: _State) -> bool:
        fixer.states["robot_0"] = state
        state.last_odom = odom.copy()
        out = fixer.step("robot_0", odom, fix_age=100.0, speed=0.0, ranges=ranges, is_leader=True)
        return out is not None and state.scan is not None

    refused = np.array([0.5, 0.0, 0.0])
    # just scanned (driven 0 m): no new scan, unless the last fix was refused and retries remain
    assert not starts_scan(_State(np.zeros(3), np.eye(3) * 1e-3, driven_since_scan=0.0))
    assert starts_scan(_State(np.zeros(3), np.eye(3) * 1e-3, driven_since_scan=0.0, refused=refused, retries=1))
    assert not starts_scan(_State(np.zeros(3), np.eye(3) * 1e-3, driven_since_scan=0.0, refused=refused, retries=2))
    # driven far enough, a scan starts anyway and the retry count starts over
    st = _State(np.zeros(3), np.eye(3) * 1e-3, driven_since_scan=2.5, refused=refused, retries=2)
    assert starts_scan(st) and st.retries == 0


def test_a_leader_due_for_a_scan_brakes_until_it_stands_still():
    from parcover_env.expert.config import SonarFixConfig

    fixer = _fixer(SonarFixConfig(stop_speed=0.005))
    odom, ranges = np.array([1.0, 1.0, 0.0]), np.full(len(fixer.beams), 1.0)
    due = {"fix_age": 100.0, "ranges": ranges, "is_leader": True}
    assert fixer.step("robot_0", odom, speed=0.02, **due) == (0.0, 0.0)  # still rolling: brake
    assert fixer.states["robot_0"].scan is None
    assert fixer.step("robot_0", odom, speed=0.004, **due) == (0.0, fixer.scan_rate)  # standing: turn
    np.testing.assert_array_equal(fixer.states["robot_0"].scan_odom, odom)


def test_scans_without_a_fix_widen_the_next_gate_until_a_fix():
    from parcover_env.expert.config import SonarFixConfig
    from parcover_env.expert.sonar_fix import _State

    fixer = _fixer(SonarFixConfig(miss_inflation=2.0, max_inflation=8.0, refused_rescans=2))
    st = _State(np.zeros(3), np.diag([0.01, 0.04, 0.001]), scan_odom=np.array([1.0, 1.0, 0.0]))
    st.scan = type("Scan", (), {"ranges": np.full(fixer.n_bins, fixer.sonar.range_max)})()  # no echo at all
    for expected in (2.0, 4.0, 8.0, 8.0):
        st.scan_cov = st.cov * st.inflation**2
        fixer._localize(st, np.zeros((0, 2)))
        assert st.missed and st.inflation == expected
    # the gate of the next scan: standard deviations x 8
    odom, ranges = np.array([1.0, 1.0, 0.0]), np.full(len(fixer.beams), 1.0)
    fixer.states["robot_0"], st.scan, st.last_odom, st.driven_since_scan = st, None, odom, 5.0
    fixer.step("robot_0", odom, fix_age=100.0, speed=0.0, ranges=ranges, is_leader=True)
    np.testing.assert_allclose(np.sqrt(np.diag(st.scan_cov)), 8.0 * np.sqrt(np.diag(st.cov)))
    # at what it believes is its route's end, a robot whose last scan missed scans again at once
    st.scan, st.driven_since_scan, st.retries = None, 0.0, 0
    assert fixer.step("robot_0", odom, fix_age=100.0, speed=0.0, ranges=ranges, is_leader=True, at_end=True)
    st.scan, st.retries = None, 0
    assert fixer.step("robot_0", odom, fix_age=100.0, speed=0.0, ranges=ranges, is_leader=True) is None


def test_chain_pose_covariance_with_a_lateral_offset_turns_with_the_robot_ahead():
    from parcover_env.expert.sonar_fix import chain_pose

    ahead, rel = np.array([1.0, 2.0, 0.7]), np.array([0.4, 0.3, 0.2])  # 0.5 m away, to the left, turned
    var_heading = 0.05**2
    pose, cov = chain_pose(ahead, np.diag([0.0, 0.0, var_heading]), rel, 0.02, 0.01, 0.03)
    np.testing.assert_allclose(compose(pose, rel), ahead, atol=1e-12)  # the camera would see `rel` from there
    t = inverse(rel)[:2]
    swing = np.array([[np.cos(ahead[2] + np.pi / 2), -np.sin(ahead[2] + np.pi / 2)],
                      [np.sin(ahead[2] + np.pi / 2), np.cos(ahead[2] + np.pi / 2)]]) @ t  # d(position)/d(theta)
    lateral = 0.25 * (0.02**2 + 0.01**2 + 0.03**2)  # d^2 = 0.4^2 + 0.3^2
    np.testing.assert_allclose(cov[:2, :2], np.outer(swing, swing) * var_heading + lateral * np.eye(2), atol=1e-15)
    np.testing.assert_allclose(cov[:2, 2], swing * var_heading, atol=1e-15)
    assert cov[2, 2] == pytest.approx(var_heading + 0.03**2)


def _scan_at(fixer, true):
    from parcover_env.sensors.sonar import simulate_beams

    ranges = simulate_beams(fixer.sonar, true[None, :2], (true[2] + fixer.team.scan_angles)[None, :],
                            fixer.team.map.segments, np.zeros((0, 2)), fixer.team.radius, np.array([-1]))[0]
    return type("Scan", (), {"ranges": ranges})()


def test_localize_accepts_a_fix_in_the_gate_refuses_one_outside_until_confirmed():
    from parcover_env.expert.config import SonarFixConfig
    from parcover_env.expert.sonar_fix import _State

    fixer = _fixer(SonarFixConfig(miss_inflation=2.0))
    true = np.array([1.0, 1.0, 0.3])  # a corner of the tree map: the scan localizes exactly
    # odometry 11 cm off, covariance 10 cm: the fix is taken and replaces the belief
    st = _State(np.zeros(3), np.diag([0.01, 0.01, 0.001]), scan_odom=true + [0.1, -0.05, 0.02])
    st.scan, st.scan_cov, st.missed, st.inflation = _scan_at(fixer, true), st.cov.copy(), True, 4.0
    fixer._localize(st, np.zeros((0, 2)))
    np.testing.assert_allclose(compose(st.correction, st.scan_odom), true, atol=1e-3)
    np.testing.assert_allclose(st.cov, fixer.fix_cov)
    assert (st.missed, st.inflation, st.refused, fixer.stats["sonar_localized"]) == (False, 1.0, None, 1)
    # odometry 0.45 m off with a 1 cm covariance (a push): the fix lies outside the gate and is
    # refused but remembered; the next scan (gate twice as wide, or confirming it) takes it
    odom = true + [0.45, 0.0, 0.0]
    st = _State(np.zeros(3), np.diag([1e-4, 1e-4, 1e-4]), scan_odom=odom)
    st.scan, st.scan_cov = _scan_at(fixer, true), st.cov.copy()
    fixer._localize(st, np.zeros((0, 2)))
    assert not np.any(st.correction) and st.missed and st.inflation == 2.0
    np.testing.assert_allclose(compose(st.refused, odom), true, atol=1e-3)
    st.scan_cov = st.cov * st.inflation**2
    fixer._localize(st, np.zeros((0, 2)))
    np.testing.assert_allclose(compose(st.correction, odom), true, atol=1e-3)
    assert (st.missed, st.inflation, st.refused) == (False, 1.0, None)
    # 0.6 m off: nothing in the first gates; each miss doubles its standard deviations until the
    # true pose is inside (here at x8)
    odom = true + [0.6, 0.0, 0.0]
    st = _State(np.zeros(3), np.diag([1e-4, 1e-4, 1e-4]), scan_odom=odom)
    st.scan, inflations = _scan_at(fixer, true), []
    while not np.any(st.correction) and len(inflations) < 6:
        st.scan_cov = st.cov * st.inflation**2
        inflations.append(st.inflation)
        fixer._localize(st, np.zeros((0, 2)))
    assert inflations == [1.0, 2.0, 4.0, 8.0]
    np.testing.assert_allclose(compose(st.correction, odom), true, atol=1e-3)


def test_localize_does_not_use_a_fix_the_scan_does_not_pin_down():
    from parcover_env.expert.config import SonarFixConfig
    from parcover_env.expert.sonar_fix import _State

    true = np.array([1.0, 1.0, 0.3])
    for threshold, used in ((0.003, True), (1.0, False)):  # no scan raises its error by 1 m when shifted
        fixer = _fixer(SonarFixConfig(min_shift_increase=threshold))
        st = _State(np.zeros(3), np.diag([0.01, 0.01, 0.001]), scan_odom=true + [0.1, -0.05, 0.02])
        st.scan, st.scan_cov = _scan_at(fixer, true), st.cov.copy()
        fixer._localize(st, np.zeros((0, 2)))
        assert bool(np.any(st.correction)) is used and st.missed is not used and st.refused is None


def _env_fixer(cfg):
    from parcover_env.expert.sonar_fix import SonarFixer

    return SonarFixer(parcover_env.load_scenario("tree"), np.radians(np.arange(0, 360, 45.0)), 0.1, cfg, env_scan=True)


def test_with_the_env_service_a_miss_or_a_kpoi_ahead_starts_the_next_scan_at_once():
    """The env's scan ended without a fix (its next region is wider): the leader asks again at once, up
    to ``refused_rescans`` times; a KPOI ahead (``check``) makes a stale leader scan whatever it drove."""
    from parcover_env.expert.config import SonarFixConfig
    from parcover_env.expert.sonar_fix import SCAN_REQUEST, _State

    fixer = _env_fixer(SonarFixConfig(refused_rescans=2, rescan_distance=2.0))
    odom, ranges = np.array([1.0, 1.0, 0.0]), np.full(len(fixer.beams), 1.0)

    def asks(state: _State, check: bool = False, fix_age: float = 100.0):
        fixer.states["robot_0"] = state
        state.last_odom = odom.copy()
        return fixer.step("robot_0", odom, fix_age=fix_age, speed=0.0, ranges=ranges, is_leader=True,
                          check=check) == SCAN_REQUEST

    def state(**kw):
        return _State(np.zeros(3), np.eye(3) * 1e-3, driven_since_scan=0.0, **kw)

    assert not asks(state())  # just scanned, no miss: drive rescan_distance first
    assert asks(state(missed=True, retries=1))
    assert not asks(state(missed=True, retries=2))
    assert asks(state(), check=True)  # a KPOI ahead
    assert not asks(state(), check=True, fix_age=1.0)  # ... unless a fix is recent
    # the env's scan: held still while it lasts, then a miss without a fresh fix is booked
    st = state(missed=False)
    assert asks(st, check=True) and st.scan == "env"
    assert fixer.step("robot_0", odom, fix_age=100.0, speed=0.0, ranges=ranges, is_leader=True,
                      scanning=True) == (0.0, 0.0)
    fixer.step("robot_0", odom, fix_age=100.0, speed=0.0, ranges=ranges, is_leader=True, scanning=False)
    assert st.scan is None and st.missed and fixer.stats["sonar_failed"] == 1
    # the own loop (no env service) keeps its rule: a miss away from the route's end waits for the drive
    own = _fixer(SonarFixConfig(refused_rescans=2, rescan_distance=2.0))
    own.states["robot_0"] = s = state(missed=True)
    s.last_odom = odom.copy()
    assert own.step("robot_0", odom, fix_age=100.0, speed=0.0, ranges=ranges, is_leader=True) is None


def test_expert_checks_its_pose_by_a_scan_before_each_kpoi():
    env = parcover_env.parallel_env("generated:3", overrides={"observation": {"scan": {"enabled": True}}})
    expert = expert_for(env)
    obs, _ = env.reset(seed=3)
    expert.reset(obs)
    o = obs["robot_0"]
    # robot 0's route ends at KPOI 2; the check reads the goal it steers by, its own tracker's (issue 42)
    route, kpoi = env.mission.routes[0], env.mission.kpois[2]
    np.testing.assert_allclose([route[-1], kpoi], [[2.58, 0.32], [2.59, 0.35]], atol=0.01)
    expert.track.progress[0] = 9.2  # the goal: the route's end (lookahead 0.3 m, clamped at the KPOI vertex)
    np.testing.assert_allclose(expert.track.goals()[0], route[-1])
    back = (route[-2] - route[-1]) / np.hypot(*(route[-2] - route[-1]))
    pose = np.r_[route[-1] + 0.5 * back, 0.3]
    assert expert._kpoi_check("robot_0", o, pose) == 2  # 0.5 m before KPOI 2: check
    far = np.r_[route[-1] + 0.7 * back, 0.3]
    assert expert._kpoi_check("robot_0", o, far) is None  # beyond kpoi_check_distance
    expert.track.progress[0] = 4.0  # a goal mid-route, on no KPOI
    goal = expert.track.goals()[0]
    assert np.hypot(*(env.mission.kpois - goal).T).min() > 1.0
    assert expert._kpoi_check("robot_0", o, np.r_[goal - [0.3, 0.0], 0.0]) is None
    expert.track.progress[0] = 9.2
    expert.checked.add(("robot_0", 2))
    assert expert._kpoi_check("robot_0", o, pose) is None  # once per robot and KPOI
