"""The env's sonar localization service (``localization/sonar/service.py``) on hand-built situations, without an
env: the scan's duration, the bookkeeping of scans under way and of their outcomes, the search region's
widening, and the gate's edges."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import parcover_env
from parcover_env.localization.estimator import FixRequest
from parcover_env.localization.sonar.service import (
    ACCEPTED,
    HELD,
    REJECTED,
    UNINFORMATIVE,
    SonarFixes,
    scan_steps,
    scan_turn,
)
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.map_model import MapModel


def _scenario(**scan):
    sc = parcover_env.load_scenario("t_room")
    return replace(sc, observation=replace(sc.observation, scan=replace(sc.observation.scan, enabled=True, **scan)))


def _service(n_robots: int = 3, **scan) -> SonarFixes:
    sc = _scenario(**scan)
    return SonarFixes(sc, MapModel.from_config(sc.map).segments, n_robots)


def _request(n: int = 3, cov: np.ndarray | None = None) -> FixRequest:
    poses = np.array([[1.0 + k, 1.0, 0.0] for k in range(n)])
    return FixRequest(0.0, poses, poses.copy(), np.zeros(n, bool), cov)


def test_a_scan_lasts_the_turn_over_the_turn_rate_in_whole_control_steps():
    sc = _scenario()
    turn, dt = scan_turn(SonarRing(sc.robot.sonar).beam_angles), sc.physics.control_dt
    assert (turn, dt, sc.robot.max_turn_rate) == (pytest.approx(math.radians(72.0)), 0.1, 1.5)
    # a turn of exactly 20 or 10 control steps takes 20 or 10, not one more
    assert scan_steps(_scenario(turn_rate=turn / (20 * dt))) == 20
    assert scan_steps(_scenario(turn_rate=turn / (10 * dt))) == 10
    # faster than the robot can turn: at max_turn_rate, 1.5 rad/s (72 degrees in 0.84 s)
    assert scan_steps(_scenario(turn_rate=turn / (5 * dt))) == 9
    # a dense ring (1 degree between transducers) reads every direction within one step
    dense = replace(sc, robot=replace(sc.robot, sonar=replace(sc.robot.sonar, layout="ring", n_beams=360)))
    assert scan_steps(dense) == 1


def test_a_request_starts_scans_only_of_robots_not_scanning_and_holds_every_scanning_robot():
    svc = _service()
    n = svc.duration_steps
    commands = np.ones((3, 2))
    svc.request(np.array([1.0, 0.0, -1.0]), commands)
    np.testing.assert_array_equal(svc.remaining, [n, 0, 0])
    np.testing.assert_array_equal(commands, [[0.0, 0.0], [1.0, 1.0], [1.0, 1.0]])
    svc.remaining[0] = 3  # under way: a new request does not restart it
    commands = np.ones((3, 2))
    svc.request(np.array([1.0, 1.0, 0.0]), commands)
    np.testing.assert_array_equal(svc.remaining, [3, n, 0])
    np.testing.assert_array_equal(svc.scanning, [True, True, False])
    np.testing.assert_array_equal(commands, [[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]])


def _stub_scans(svc: SonarFixes, results):
    """Replace ``svc.localize_scan``: each call returns the next of ``results`` ((pose or None, informative))."""
    it = iter(results)
    svc.localize_scan = lambda i, request, rng: next(it)


def test_outcomes_of_scans_ending_now_and_the_widening_of_the_next_region():
    svc = _service(miss_inflation=2.0, max_inflation=8.0)
    rng, req = np.random.default_rng(0), _request()
    svc.remaining[:] = [1, 2, 0]
    _stub_scans(svc, [(None, True)])
    assert svc.fixes(req, rng) == {}  # robot 0's scan ends: rejected; robot 1's goes on
    np.testing.assert_array_equal(svc.remaining, [0, 1, 0])
    np.testing.assert_array_equal(svc.outcome, [REJECTED, 0.0, 0.0])
    np.testing.assert_array_equal(svc.inflation, [2.0, 1.0, 1.0])
    _stub_scans(svc, [(None, False)])
    assert svc.fixes(req, rng) == {}  # robot 1: uninformative, its region stays
    np.testing.assert_array_equal(svc.outcome, [0.0, UNINFORMATIVE, 0.0])  # this step's only
    np.testing.assert_array_equal(svc.result, [REJECTED, UNINFORMATIVE, 0.0])  # the last of each
    np.testing.assert_array_equal(svc.inflation, [2.0, 1.0, 1.0])
    for expected in (4.0, 8.0, 8.0):  # rejected again and again: at most max_inflation
        svc.remaining[0] = 1
        _stub_scans(svc, [(None, True)])
        svc.fixes(req, rng)
        assert svc.inflation[0] == expected
    pose = np.array([1.05, 0.98, 0.01])
    svc.remaining[0] = 1
    _stub_scans(svc, [(pose, True)])  # confirm_widened off: every fix is applied
    out = svc.fixes(req, rng)
    assert list(out) == [0] and out[0] is pose
    assert svc.outcome[0] == svc.result[0] == ACCEPTED and svc.inflation[0] == 1.0
    svc.remaining[:] = [0, 0, 0]
    assert svc.fixes(req, rng) == {} and not svc.outcome.any()


def test_reset_forgets_every_scan_outcome_widening_and_held_fix():
    svc = _service()
    svc.remaining[:], svc.result[:], svc.outcome[:], svc.inflation[:] = 2, HELD, HELD, 4.0
    svc.held = [np.ones(3)] * 3
    svc.held_from = [np.ones(3)] * 3
    svc.reset(np.random.default_rng(0))
    assert not svc.remaining.any() and not svc.result.any() and not svc.outcome.any()
    np.testing.assert_array_equal(svc.inflation, np.ones(3))
    assert svc.held == [None] * 3 and svc.held_from == [None] * 3


def test_a_fix_on_the_edge_of_the_gate_is_inside():
    # gate_distance 0.75 m over 3 sigmas: a position sigma of 0.25 m with a zero covariance; heading 36 deg
    svc = _service(gate_distance=0.75, gate_sigmas=3.0, gate_heading_deg=36.0, gate_heading_max_deg=40.0)
    prior, cov = np.array([1.0, 1.0, 0.0]), np.zeros((3, 3))
    assert svc.in_gate(np.array([1.75, 1.0, 0.0]), prior, cov)  # 3 sigmas exactly
    assert not svc.in_gate(np.array([1.75 + 1e-9, 1.0, 0.0]), prior, cov)
    assert svc.in_gate(np.array([1.0, 1.0, math.radians(36.0)]), prior, cov)  # 36 degrees exactly
    assert not svc.in_gate(np.array([1.0, 1.0, math.radians(36.0) + 1e-9]), prior, cov)
    # a heading variance a rounding error below 0 counts as 0
    pos, turn = svc.gate(np.diag([0.0, 0.0, -1e-18]))
    assert turn == math.radians(36.0)
    np.testing.assert_array_equal(pos, np.eye(2) * 0.0625)


def test_a_held_fix_is_confirmed_only_by_a_scan_at_least_shift_test_from_where_it_was_found():
    from parcover_env.geometry.poses import compose, inverse

    svc = _service(confirm_widened=True, shift_test=0.25, gate_distance=0.15, gate_sigmas=3.0)
    cov = np.zeros((3, 3, 3))
    est = np.array([[1.0, 1.0, 0.0], [3.0, 1.0, 0.0], [5.0, 1.0, 0.0]])
    req = FixRequest(0.0, est.copy(), est, np.zeros(3, bool), cov)
    far = np.array([1.6, 1.0, 0.0])  # 0.6 m off: outside the base gate (3 x 0.05 m widened by the fix sigma)
    assert not svc.in_gate(far, est[0], cov[0])
    assert not svc.confirmed(0, far, req)  # nothing held yet: this one is held
    np.testing.assert_allclose(compose(svc.held[0], est[0]), far, atol=1e-12)
    np.testing.assert_array_equal(svc.held_from[0], est[0])
    # found again from exactly shift_test away (0.25 m): from elsewhere, it agrees: confirmed
    svc.held_from[0] = est[0] + [0.0, -0.25, 0.0]
    assert svc.confirmed(0, far, req)
    # from closer (0.2 m): the same scene, neither confirmed nor replaced
    svc.held_from[0] = est[0] + [0.0, -0.2, 0.0]
    other = far + [0.0, 0.5, 0.0]
    assert not svc.confirmed(0, other, req)
    np.testing.assert_allclose(compose(svc.held[0], est[0]), far, atol=1e-12)
    # a fix inside the base gate is applied at once, whatever is held; without confirm_widened all are
    assert svc.confirmed(0, est[0] + [0.1, 0.0, 0.0], req)
    assert _service(confirm_widened=False).confirmed(0, far, req)
    # the gate is that of the estimate's covariance: sigma 0.2 m admits a fix 0.4 m off at once
    loose = FixRequest(0.0, est.copy(), est, np.zeros(3, bool), np.stack([np.diag([0.04, 0.04, 0.01])] * 3))
    assert svc.confirmed(2, est[2] + [0.4, 0.0, 0.0], loose) and svc.held[2] is None
    # no covariance in the request: the gate is that of a zero covariance (gate_distance only)
    bare = FixRequest(0.0, est.copy(), est, np.zeros(3, bool), None)
    assert svc.confirmed(1, est[1] + [0.14, 0.0, 0.0], bare)
    assert not svc.confirmed(1, est[1] + [0.16, 0.0, 0.0], bare) and svc.held[1] is not None
    np.testing.assert_allclose(svc.held[1], compose(est[1] + [0.16, 0.0, 0.0], inverse(est[1])), atol=1e-12)


TRUE = np.array([2.0, 0.5, math.pi / 2])  # robot 0 of t_room after reset(seed=0), facing up its room
"""A pose whose noise-free ring scan the localizer matches exactly."""


def test_the_search_region_is_gate_sigmas_of_the_covariance_times_the_inflation():
    # sigma 0.05 m widened by gate_distance / gate_sigmas = 0.05 m: the 3-sigma region's radius is
    # 3 sqrt(0.05^2 k^2 + 0.05^2) for inflation k: 0.21 m (k = 1), 0.34 m (2), 0.47 m (3)
    svc = _service(n_robots=1)
    ranges = svc.ring.scan(TRUE, svc.segments, np.zeros((0, 2)), svc.radius, None)
    cov = np.diag([0.05**2, 0.05**2, 0.02**2])[None]
    found = {}
    for off in (0.3, 0.43, 0.5):
        est = (TRUE + [off, 0.0, 0.0])[None]
        req = FixRequest(0.0, TRUE[None], est, np.zeros(1, bool), cov)
        found[off] = [svc.match(0, ranges, req, k)[0] is not None for k in (1.0, 2.0, 3.0)]
    assert found == {0.3: [False, True, True], 0.43: [False, False, True], 0.5: [False, False, False]}
    pose, informative = svc.match(0, ranges, FixRequest(0.0, TRUE[None], (TRUE + [0.43, 0.0, 0.0])[None],
                                                        np.zeros(1, bool), cov), 3.0)
    np.testing.assert_allclose(pose, TRUE, atol=1e-6)
    assert informative
    # no covariance in the request: the region of a zero covariance, gate_distance (0.15 m)
    for off, hit in ((0.1, True), (0.3, False)):
        req = FixRequest(0.0, TRUE[None], (TRUE + [off, 0.0, 0.0])[None], np.zeros(1, bool), None)
        assert (svc.match(0, ranges, req, 1.0)[0] is not None) is hit


MATES = np.array([TRUE, [2.0, 0.95, 0.0], [1.6, 0.5, 0.0]])  # robot 1 0.45 m ahead, robot 2 0.4 m to the side
"""Robot 0 and two teammates next to it that block several of its readings."""


def test_readings_a_teammate_may_explain_are_left_out_of_the_match():
    svc = _service()
    ranges = svc.ring.scan(TRUE, svc.segments, MATES[1:, :2], svc.radius, None)
    others = np.array([1, 2])

    def matches(cov, estimate=MATES, share=None, which=others):
        s = svc if share is None else _service(min_unmasked_share=share)
        return s.matches_unmasked(TRUE, ranges, FixRequest(0.0, MATES, estimate, np.zeros(3, bool), cov), which)

    # teammates known to 0.2 m (major axis; 0.1 m across): readings ending within 0.165 + 2 x 0.2 m of
    # them are left out, the rest match the known map; robot 0's own covariance plays no part
    known = np.stack([np.eye(3) * 0.25, np.diag([0.01, 0.04, 0.0]), np.diag([0.04, 0.01, 0.0])])
    assert matches(known)
    assert not matches(None)  # exact teammates: only readings ending on their discs; some echoes miss that
    assert not matches(known, estimate=MATES + [1.5, 0.0, 0.0])  # believed elsewhere: they explain nothing
    assert not matches(known, which=np.array([], dtype=int))  # no teammates: nothing to leave out
    # teammates known to 0.5 m: they may explain 50 of the 72 readings; 22 left match the map, but
    # the share left must be at least min_unmasked_share
    lost = np.stack([np.eye(3) * 0.25] * 3)
    assert not matches(lost)
    assert matches(lost, share=22 / 72) and not matches(lost, share=23 / 72)


def test_a_match_fails_or_passes_on_the_readings_no_teammate_may_explain():
    svc = _service()
    ranges = svc.ring.scan(TRUE, svc.segments, MATES[1:, :2], svc.radius, None)
    known = np.stack([np.diag([0.01, 0.01, 0.0004]), np.diag([0.01, 0.04, 0.0]), np.diag([0.04, 0.01, 0.0])])

    def match(shift, s=svc):
        est = MATES + [0.0, shift, 0.0]  # the teammates believed ``shift`` m further up
        est[0] = TRUE + [0.05, 0.0, 0.0]
        return s.match(0, ranges, FixRequest(0.0, MATES, est, np.zeros(3, bool), known), 1.0)[0]

    # believed 0.2 m off: drawn in there, they spoil the plain match; the readings they may explain
    # left out (reach 0.165 + 2 x 0.2 m), the rest match: a fix near the truth
    pose = match(0.2)
    assert pose is not None and np.hypot(*(pose[:2] - TRUE[:2])) < 0.15
    assert match(0.2, _service(min_unmasked_share=1.0)) is None  # no reading may be left out: no fix
    assert match(0.25) is None  # 0.25 m off: the readings left do not match either


def test_the_heading_search_is_the_gate_of_the_heading_sigma():
    # heading sigma 4 degrees: 30 + 3 x 4 = 42 -> at most 40 degrees, beyond the localizer's own 30
    svc = _service(n_robots=1)
    ranges = svc.ring.scan(TRUE, svc.segments, np.zeros((0, 2)), svc.radius, None)
    for sigma_deg, found in ((0.0, False), (4.0, True)):
        cov = np.diag([0.05**2, 0.05**2, math.radians(sigma_deg) ** 2])[None]
        req = FixRequest(0.0, TRUE[None], (TRUE + [0.0, 0.0, math.radians(35.0)])[None], np.zeros(1, bool), cov)
        assert (svc.match(0, ranges, req, 1.0)[0] is not None) is found


def test_the_service_localizes_with_the_scenarios_localizer_settings():
    sc = _scenario()
    strict = replace(sc, sonar_localizer={**sc.sonar_localizer, "success_error": 1e-9})
    svc = _service(n_robots=1)
    ranges = svc.ring.scan(TRUE, svc.segments, np.zeros((0, 2)), svc.radius, None)
    req = FixRequest(0.0, TRUE[None], (TRUE + [0.05, 0.0, 0.0])[None], np.zeros(1, bool),
                     np.diag([0.05**2, 0.05**2, 0.02**2])[None])
    assert svc.match(0, ranges, req, 1.0)[0] is not None
    # a success error no real scan reaches (1e-9 m): nothing is accepted
    assert SonarFixes(strict, svc.segments, 1).match(0, ranges, req, 1.0)[0] is None


def test_the_scan_is_simulated_with_the_generator_of_the_step():
    svc = _service(n_robots=1)
    req = FixRequest(0.0, TRUE[None], (TRUE + [0.05, 0.0, 0.0])[None], np.zeros(1, bool),
                     np.diag([0.05**2, 0.05**2, 0.02**2])[None])
    poses = [svc.localize_scan(0, req, np.random.default_rng(seed))[0] for seed in (0, 1, 0)]
    assert all(p is not None and np.hypot(*(p[:2] - TRUE[:2])) < 0.05 for p in poses)
    assert not np.array_equal(poses[0], poses[1])  # the sonar's noise differs with the generator ...
    np.testing.assert_array_equal(poses[0], poses[2])  # ... and repeats with it
    seen = []
    svc.localize_scan = lambda i, request, rng: seen.append(rng) or (None, True)
    svc.remaining[0] = 1
    rng = np.random.default_rng(5)
    svc.fixes(req, rng)
    assert seen == [rng]


def _stub_match(svc: SonarFixes, widened, base):
    """Replace ``svc.match``: ``widened`` for a search with inflation > 1, ``base`` for inflation 1;
    returns the list of inflations searched."""
    calls = []

    def match(i, ranges, request, inflation):
        calls.append(inflation)
        pose = widened if inflation > 1 else base
        return (None if pose is None else pose.copy()), True

    svc.match = match
    return calls


def test_after_one_rejected_scan_a_far_match_gives_way_to_one_inside_the_base_gate():
    svc = _service(n_robots=1, confirm_widened=True)
    est = TRUE + [0.05, 0.0, 0.0]
    cov = np.diag([0.05**2, 0.05**2, 0.02**2])
    far, near = est + [0.0, 1.2, 0.0], est + [-0.04, 0.01, 0.01]
    req = FixRequest(0.0, TRUE[None], est[None], np.zeros(1, bool), cov[None])
    svc.inflation[0] = 2.0  # one rejected scan: the region is twice as wide
    calls = _stub_match(svc, far, near)
    pose, _ = svc.localize_scan(0, req, np.random.default_rng(0))
    np.testing.assert_array_equal(pose, near)
    assert calls == [2.0, 1.0]
    # the base gate is that of the estimate's covariance: 0.4 m off is inside with sigma 0.2 m
    loose = FixRequest(0.0, TRUE[None], est[None], np.zeros(1, bool), np.diag([0.04, 0.04, 0.01])[None])
    calls = _stub_match(svc, est + [0.4, 0.0, 0.0], near)
    pose, _ = svc.localize_scan(0, loose, np.random.default_rng(0))
    np.testing.assert_array_equal(pose, est + [0.4, 0.0, 0.0])
    assert calls == [2.0]
    # no covariance in the request: the base gate of a zero covariance (0.15 m)
    bare = FixRequest(0.0, TRUE[None], est[None], np.zeros(1, bool), None)
    calls = _stub_match(svc, est + [0.1, 0.0, 0.0], near)
    np.testing.assert_array_equal(svc.localize_scan(0, bare, np.random.default_rng(0))[0], est + [0.1, 0.0, 0.0])
    calls = _stub_match(svc, est + [0.2, 0.0, 0.0], near)
    np.testing.assert_array_equal(svc.localize_scan(0, bare, np.random.default_rng(0))[0], near)
    assert calls == [2.0, 1.0]


def test_the_ring_sees_the_teammates_at_their_true_poses_and_the_map_draws_them_at_their_estimates():
    svc = _service()
    est = MATES.copy()
    est[0] = TRUE + [0.05, 0.0, 0.0]
    # the teammates next to robot 0, believed where they are: their echoes are explained, a fix
    pose, _ = svc.localize_scan(0, FixRequest(0.0, MATES, est, np.zeros(3, bool), None), None)
    assert pose is not None and np.hypot(*(pose[:2] - TRUE[:2])) < 0.01
    # believed 1.5 m away: the ring still sees them (at their true poses), the map does not: no fix
    far = MATES + [0.0, 1.5, 0.0]
    far[0] = est[0]
    assert svc.localize_scan(0, FixRequest(0.0, MATES, far, np.zeros(3, bool), None), None)[0] is None


def test_the_pin_down_test_trims_the_worst_readings_like_the_localizer():
    """A 12 x 1.2 m corridor, sonar range 2.5 m: 2.45 m from its end wall, shifted scans raise the
    untrimmed error by 0.006 m (>= min_shift_increase 0.003 m), the best 90 % of the readings
    (``error_trim`` 0.1) by less: not pinned down. 2.3 m from the wall it is."""
    from parcover_env.config.schema import MapConfig
    from parcover_env.localization.sonar.known_map import known_map_features
    from parcover_env.sensors.sonar import simulate_beams

    sc = parcover_env.load_scenario("generated:120")
    sc = replace(sc, map=MapConfig(size=(12.0, 1.2)),
                 observation=replace(sc.observation, scan=replace(sc.observation.scan, enabled=True)))
    svc = SonarFixes(sc, known_map_features(sc.map, sc.robot.sonar.range_max)[0].segments, 1)
    assert (sc.robot.sonar.range_max, svc.cfg.shift_test, svc.cfg.min_shift_increase) == (2.5, 0.2, 0.003)
    assert svc.params.error_trim == 0.1
    for x, pinned in ((2.3, True), (2.45, False)):
        pose = np.array([x, 0.6, 0.0])
        ranges = simulate_beams(svc.ring.cfg, pose[None, :2], (pose[2] + svc.ring.scan_angles)[None, :],
                                svc.known.segments, np.zeros((0, 2)), 0.0, np.array([-1]))[0]
        assert svc.pins_down(pose, ranges, np.zeros((0, 2))) is pinned


def test_the_team_map_cuts_a_16_sided_disc_of_the_robot_radius_per_teammate():
    svc = _service()
    assert svc.team_map(np.zeros((0, 2))) is svc.known
    r, area = svc.radius, svc.known.free.area  # 4 m x 4 m minus the T's walls
    disc = 8 * r**2 * math.sin(math.pi / 8)  # quad_segs 4: 16 triangles of r^2 sin(pi / 8) / 2
    one = svc.team_map(np.array([[2.0, 1.5]]))
    assert one.free.area == pytest.approx(area - disc, rel=1e-12)
    assert one.bounds == svc.known.bounds
    apart = svc.team_map(np.array([[2.0, 1.5], [2.0, 0.95]]))
    assert apart.free.area == pytest.approx(area - 2 * disc, rel=1e-12)


def test_the_unmasked_readings_are_compared_with_the_map_seen_from_the_pose_off_its_symmetry_axis():
    # robot 0 off the room's axis and turned: a scan mirrored about its heading would not match
    true = np.array([1.7, 0.6, math.pi / 2 + 0.2])
    mates = np.array([true, [1.75, 1.05, 0.0], [1.3, 0.6, 0.0]])
    svc = _service()
    ranges = svc.ring.scan(true, svc.segments, mates[1:, :2], svc.radius, None)
    known = np.stack([np.eye(3) * 0.25, np.diag([0.01, 0.04, 0.0]), np.diag([0.04, 0.01, 0.0])])
    others = np.array([1, 2])
    assert svc.matches_unmasked(true, ranges, FixRequest(0.0, mates, mates, np.zeros(3, bool), known), others)
    assert not svc.matches_unmasked(true, ranges, FixRequest(0.0, mates, mates, np.zeros(3, bool), None), others)
    # one teammate beside robot 0 (of TRUE): the readings ending on its disc left out, the rest match
    ranges = svc.ring.scan(TRUE, svc.segments, MATES[2:, :2], svc.radius, None)
    assert svc.matches_unmasked(TRUE, ranges, FixRequest(0.0, MATES, MATES, np.zeros(3, bool), None), np.array([2]))
