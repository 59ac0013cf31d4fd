"""The env's sonar localization service (``observation.scan``): a scan holds the robot still for the
documented time, Kim, Pearce & Amato's localizer fixes the estimate from its own prior, a rejected
scan changes nothing, and rollouts stay deterministic (copies, batched worlds)."""

from __future__ import annotations

import copy
import math
import pickle

import numpy as np
import pytest

import parcover_env
from parcover_env.errors import ActionError
from parcover_env.localization.sonar.service import ACCEPTED, HELD, REJECTED, UNINFORMATIVE, scan_steps, scan_turn

SCAN = {"observation": {"scan": {"enabled": True}, "pose_source": "odometry"}}
CONFIRM = {"observation": {"scan": {"enabled": True, "confirm_widened": True}, "pose_source": "odometry"}}


def _env(overrides=SCAN, scenario="t_room"):
    env = parcover_env.parallel_env(scenario, overrides=overrides)
    env.reset(seed=0)
    return env


def _act(env, v=0.0, w=0.0, scan=-1.0):
    return {a: np.array([v, w, scan], np.float32) for a in env.agents}


def _scan(env):
    """Request a scan for robot 0 (the others idle) and step until 2 steps after it ends; per-step
    records. Robot 0 commands full speed while scanning (ignored: held still), then stands."""
    rows = []
    for k in range(env.scanner.duration_steps + 2):
        acts = _act(env)
        if k < env.scanner.duration_steps:
            acts["robot_0"] = np.array([1.0, 1.0, 1.0 if k == 0 else -1.0], np.float32)
        obs, _, _, _, infos = env.step(acts)
        rows.append((env.layout.get(obs["robot_0"], "scanning")[0], env.layout.get(obs["robot_0"], "scan_result")[0],
                     infos["robot_0"]["sonar_fix"]))
    return rows


def test_scan_duration_is_the_real_robots_turn():
    env = _env()
    s = env.scenario
    assert s.robot.sonar.layout == "amigobot" and s.robot.max_turn_rate > 0.6
    assert scan_turn(env.sonar.beam_angles) == pytest.approx(math.radians(72.0))  # the two rear transducers
    assert env.scanner.duration_steps == scan_steps(s) == math.ceil(math.radians(72.0) / 0.6 / s.physics.control_dt)
    assert scan_steps(s) == 21  # 0.6 rad/s, 0.1 s control step: 2.1 s
    assert scan_turn(np.radians([0.0, 90.0, 180.0, 270.0])) == pytest.approx(math.pi / 2)
    assert scan_turn(np.array([0.3])) == pytest.approx(2 * math.pi)
    slow = parcover_env.parallel_env("t_room", overrides={"observation": {"scan": {"enabled": True, "turn_rate": 0.3}}})
    assert slow.scanner.duration_steps == 42
    assert env.action_space("robot_0").shape == (3,)
    assert {"scanning", "scan_result"} <= set(env.layout.names)


def test_default_env_is_unchanged_and_rejects_a_scan_component():
    env = parcover_env.parallel_env("t_room")
    env.reset(seed=0)
    assert env.action_space("robot_0").shape == (2,) and env.scanner is None
    assert "scanning" not in env.layout.names and "sonar_fix" not in env.step(
        {a: np.zeros(2, np.float32) for a in env.agents})[4]["robot_0"]
    with pytest.raises(ActionError, match=r"shape \(2,\)"):
        env.step({a: np.zeros(3, np.float32) for a in env.agents})


def test_scan_with_a_known_answer_fixes_the_drifted_estimate():
    env = _env()
    true = env.true_poses()[0].copy()
    drifted = true + np.array([0.15, -0.10, 0.03])
    prior = np.diag([0.1**2, 0.1**2, 0.05**2])
    env.estimator.fix(0, drifted, prior)  # a drifted estimate whose covariance holds the truth
    t0 = env.world.time
    rows = _scan(env)
    n = env.scanner.duration_steps
    assert [r[0] for r in rows] == [1.0] * (n - 1) + [0.0] * 3  # scanning during, 0 after
    assert [r[2] for r in rows] == [0.0] * (n - 1) + [ACCEPTED, 0.0, 0.0]  # info: this step's outcome
    assert rows[-1][1] == ACCEPTED
    after = env.true_poses()[0]
    np.testing.assert_allclose(after, true, atol=1e-9)  # held still although it commanded full speed
    est = env.pose_estimates()[0]
    assert np.hypot(*(est[:2] - true[:2])) < 0.03 and abs(est[2] - true[2]) < math.radians(2)
    sth = math.radians(2.0)
    np.testing.assert_allclose(env.pose_covariances()[0], np.diag([0.05**2, 0.05**2, sth**2]), atol=1e-12)
    assert env.fix_age[0] == pytest.approx(2 * env.scenario.physics.control_dt)
    assert env.world.time - t0 == pytest.approx((n + 2) * env.scenario.physics.control_dt)


def test_a_rejected_scan_leaves_estimate_and_covariance():
    env = _env()
    true = env.true_poses()[0].copy()
    far = true + np.array([1.2, 0.8, 0.0])  # far outside its own small covariance
    cov = np.diag([0.02**2, 0.02**2, 0.01**2])
    env.estimator.fix(0, far, cov)
    rows = _scan(env)
    n = env.scanner.duration_steps
    assert rows[n - 1][2] == REJECTED and rows[-1][1] == REJECTED
    np.testing.assert_array_equal(env.pose_estimates()[0], far)  # standing still: no odometry change either
    np.testing.assert_array_equal(env.pose_covariances()[0], cov)


def test_localizer_prior_is_the_estimate_never_the_truth(monkeypatch):
    from parcover_env.localization.sonar import service as sonar_fixes

    seen = []
    orig = sonar_fixes.localize

    def spy(ranges, angles, map_model, sectors, region, *a, **kw):
        seen.append((region.center, kw["heading"]))
        return orig(ranges, angles, map_model, sectors, region, *a, **kw)

    monkeypatch.setattr(sonar_fixes, "localize", spy)
    env = _env()
    est = env.true_poses()[0] + np.array([0.1, 0.05, 0.02])
    env.estimator.fix(0, est, np.diag([0.01, 0.01, 0.001]))
    _scan(env)
    assert seen == [((pytest.approx(est[0]), pytest.approx(est[1])), pytest.approx(est[2]))]


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_copy_mid_scan_continues_identically(how):
    over = {"observation": {"scan": {"enabled": True}}}
    env = parcover_env.parallel_env("office", overrides=over)
    env.reset(seed=3)
    rng = np.random.default_rng(1)
    acts = rng.uniform(-1, 1, (140, env.n_robots, 3)).astype(np.float32)
    acts[:, :, 2] = -1.0
    acts[5, :, 2] = 1.0  # every robot starts a scan at step 5
    step = lambda e, a: e.step(dict(zip(e.possible_agents, a, strict=True)))  # noqa: E731
    mid = 6 + env.scanner.duration_steps // 2
    for a in acts[:mid]:
        step(env, a)
    assert env.scanner.scanning.all()
    twin = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    outcomes = []
    for a in acts[mid:]:
        o1, r1, _, _, i1 = step(env, a)
        o2, r2, _, _, i2 = step(twin, a)
        assert all(np.array_equal(o1[k], o2[k]) for k in o1) and r1 == r2
        assert all(repr(i1[a]) == repr(i2[a]) for a in i1)
        outcomes.append([i["sonar_fix"] for i in i1.values()])
    assert any(any(x) for x in outcomes)  # the scans ended in the copied stretch


def test_batched_worlds_scan_as_separate_envs():
    pytest.importorskip("stable_baselines3")
    from parcover_env.envs.vec_env import make_vec_env

    over = {"observation": {"scan": {"enabled": True}}, "episode": {"max_steps": 200}}
    venv = make_vec_env("office", n_envs=2, overrides=over, backend="batched", monitor=False)
    refs = [parcover_env.parallel_env("office", overrides=over) for _ in range(2)]
    venv.seed(7)
    obs = venv.reset()
    ref_obs = [e.reset(seed=7 + k)[0] for k, e in enumerate(refs)]
    n = refs[0].n_robots
    assert np.array_equal(obs, np.concatenate([np.stack([o[a] for a in refs[0].possible_agents]) for o in ref_obs]))
    rng = np.random.default_rng(2)
    for t in range(130):
        acts = rng.uniform(-1, 1, (2 * n, 3)).astype(np.float32)
        acts[:, 2] = 1.0 if t == 3 else -1.0
        obs, rew, done, infos = venv.step(acts)
        for k, e in enumerate(refs):
            o, r, _, _, inf = e.step({a: acts[k * n + i] for i, a in enumerate(e.possible_agents)})
            assert np.array_equal(obs[k * n:(k + 1) * n], np.stack([o[a] for a in e.possible_agents]))
            assert [infos[k * n + i]["sonar_fix"] for i in range(n)] == [inf[a]["sonar_fix"] for a in e.possible_agents]
    assert any(e.scanner.result.any() for e in refs)


def test_heading_gate_is_capped_below_a_quarter_turn():
    env = _env()
    c = env.scenario.observation.scan
    cov = np.diag([0.01, 0.01, math.radians(3.0) ** 2])
    pos, turn = env.scanner.gate(cov)
    assert turn == pytest.approx(math.radians(c.gate_heading_deg + c.gate_sigmas * 3.0))  # 30 + 3 x 3 deg
    np.testing.assert_allclose(pos, cov[:2, :2] + (c.gate_distance / c.gate_sigmas) ** 2 * np.eye(2))
    _, wide = env.scanner.gate(cov * 8.0**2)  # after rejected scans the heading sigma is inflated to 24 deg
    assert wide == pytest.approx(math.radians(c.gate_heading_max_deg)) == pytest.approx(math.radians(40.0))
    with pytest.raises(parcover_env.errors.ConfigError, match="gate_heading_max_deg"):
        parcover_env.parallel_env("t_room", overrides={"observation": {"scan": {"enabled": True,
                                                                             "gate_heading_max_deg": 95.0}}})


def test_a_scan_that_does_not_pin_the_pose_down_is_rejected():
    """In open space (every reading 'no echo') the localizer matches anywhere: no fix. With the shift
    test off the same scan's pose is accepted."""
    env = _env()
    sc = env.scanner
    pose = env.true_poses()[0]
    empty = np.full(len(sc.ring.scan_angles), sc.ring.cfg.range_max)
    others = env.pose_estimates()[1:, :2]
    assert not sc.pins_down(pose, empty, others)
    real = sc.ring.scan(pose, sc.segments, env.true_poses()[1:, :2], sc.radius, None)
    assert sc.pins_down(pose, real, others)
    off = parcover_env.parallel_env("t_room", overrides={"observation": {"scan": {"enabled": True, "shift_test": 0.0}}})
    off.reset(seed=0)
    assert off.scanner.pins_down(pose, empty, others)


def test_an_uninformative_scan_is_rejected_without_widening_the_next_region():
    env = _env()
    true = env.true_poses()[0].copy()
    cov = np.diag([0.05**2, 0.05**2, 0.02**2])
    env.estimator.fix(0, true + np.array([0.05, 0.0, 0.0]), cov)
    env.scanner.pins_down = lambda *args: False  # the scan matched but pins nothing down
    rows = _scan(env)
    assert rows[-1][1] == UNINFORMATIVE and rows[-1][1] < 0 and env.scanner.inflation[0] == 1.0
    env.estimator.fix(0, true + np.array([1.2, 0.8, 0.0]), np.diag([0.02**2, 0.02**2, 0.01**2]))
    _scan(env)  # no match inside the small region around a far estimate: the robot may lie outside it
    assert env.scanner.result[0] == REJECTED
    assert env.scanner.inflation[0] == env.scenario.observation.scan.miss_inflation


def _widened(env, offset, inflation=8.0):
    """Robot 0's estimate put ``offset`` (dx, dy, dheading) off its true pose, with a fresh fix's small
    covariance, after rejected scans widened its search region by ``inflation``."""
    true = env.true_poses()[0].copy()
    c = env.scenario.observation.scan
    cov = np.diag([c.fix_sigma_xy**2, c.fix_sigma_xy**2, math.radians(c.fix_sigma_heading_deg) ** 2])
    env.estimator.fix(0, true + np.asarray(offset), cov)
    env.scanner.inflation[0] = inflation
    return true, cov, true + np.asarray(offset)


def test_a_fix_found_only_in_a_widened_region_is_held_until_a_second_scan_agrees():
    from parcover_env.geometry.poses import compose

    env = _env(CONFIRM)
    sc = env.scanner
    true, cov, est = _widened(env, [0.5, -0.3, 0.2])  # 0.58 m off: outside the base gate (3 x 0.071 m), in x 8
    assert not sc.in_gate(true, est, cov) and sc.in_gate(true, est, cov * 64.0)
    rows = _scan(env)
    assert rows[-1][1] == HELD  # held, not applied: estimate and covariance unchanged
    np.testing.assert_array_equal(env.pose_estimates()[0], est)
    np.testing.assert_array_equal(env.pose_covariances()[0], cov)
    assert sc.inflation[0] == 8.0  # the region is not widened further: the second scan searches the same
    carried = compose(sc.held[0], est)  # the held fix is the localized pose (near the truth)
    assert np.hypot(*(carried[:2] - true[:2])) < 0.05 and abs(carried[2] - true[2]) < math.radians(3)
    for _ in range(25):  # drive on: the held fix is carried along by the estimate's motion
        env.step(_act(env, v=0.3))
    for _ in range(5):
        env.step(_act(env))
    moved = env.true_poses()[0].copy()
    assert np.hypot(*(moved[:2] - true[:2])) > 0.2
    carried = compose(sc.held[0], env.pose_estimates()[0])
    assert np.hypot(*(carried[:2] - moved[:2])) < 0.05
    rows = _scan(env)  # the second scan's fix agrees with the carried held fix: applied
    assert rows[-1][1] == ACCEPTED and sc.held[0] is None and sc.inflation[0] == 1.0
    est = env.pose_estimates()[0]
    assert np.hypot(*(est[:2] - moved[:2])) < 0.05 and abs(est[2] - moved[2]) < math.radians(3)


def test_a_disagreeing_second_scan_drops_the_held_fix():
    from parcover_env.geometry.poses import compose, inverse

    env = _env(CONFIRM)
    sc = env.scanner
    true, cov, est = _widened(env, [0.5, -0.3, 0.2])
    look_alike = true + np.array([0.0, 0.4, 0.0])  # an earlier held fix 0.4 m from where the scan matches
    sc.held[0] = compose(look_alike, inverse(est))
    sc.held_from[0] = est + np.array([0.3, 0.0, 0.0])  # found from 0.3 m away (>= shift_test 0.2)
    rows = _scan(env)
    assert rows[-1][1] == HELD
    np.testing.assert_array_equal(env.pose_estimates()[0], est)
    carried = compose(sc.held[0], est)  # the new fix replaced the old one: held in its place
    assert np.hypot(*(carried[:2] - true[:2])) < 0.05
    np.testing.assert_array_equal(sc.held_from[0], est)
    sc.held[0] = compose(true + np.array([0.0, 0.1, 0.0]), inverse(est))  # 0.1 m: inside a fresh fix's gate
    sc.held_from[0] = est + np.array([0.0, 0.25, 0.0])
    assert _scan(env)[-1][1] == ACCEPTED


def test_a_scan_from_where_the_held_fix_was_found_neither_confirms_nor_replaces_it():
    from parcover_env.geometry.poses import compose, inverse

    env = _env(CONFIRM)
    sc = env.scanner
    true, cov, est = _widened(env, [0.5, -0.3, 0.2])
    assert _scan(env)[-1][1] == HELD
    first = sc.held[0].copy()
    np.testing.assert_array_equal(sc.held_from[0], est)
    assert _scan(env)[-1][1] == HELD  # agrees, but from the same spot: a look-alike would repeat too
    np.testing.assert_array_equal(sc.held[0], first)
    look_alike = compose(true + np.array([0.0, 0.4, 0.0]), inverse(est))
    sc.held[0] = look_alike
    sc.held_from[0] = est + np.array([0.15, 0.0, 0.0])  # 0.15 m away: still closer than shift_test
    assert _scan(env)[-1][1] == HELD  # disagrees from the same scene: the held fix is kept
    np.testing.assert_array_equal(sc.held[0], look_alike)
    np.testing.assert_array_equal(env.pose_estimates()[0], est)


def test_a_fix_inside_the_base_gate_or_with_confirmation_off_is_applied_at_once():
    env = _env(CONFIRM)
    true, _, _ = _widened(env, [0.1, -0.05, 0.02])  # 0.11 m: inside the base gate of its own covariance
    assert _scan(env)[-1][1] == ACCEPTED and env.scanner.held[0] is None
    assert np.hypot(*(env.pose_estimates()[0][:2] - true[:2])) < 0.05
    off = _env()  # confirm_widened off (the default)
    true, _, _ = _widened(off, [0.5, -0.3, 0.2])
    assert _scan(off)[-1][1] == ACCEPTED and off.scanner.held[0] is None
    assert np.hypot(*(off.pose_estimates()[0][:2] - true[:2])) < 0.05


def _stub_match(scanner, widened, base):
    """Replace ``scanner.match``: ``widened`` (3,) or None for a search with inflation > 1, ``base`` for
    inflation 1; returns the list of inflations searched."""
    calls = []

    def match(i, ranges, request, inflation):
        calls.append(inflation)
        pose = widened if inflation > 1 else base
        return (None if pose is None else pose.copy()), True

    scanner.match = match
    return calls


def test_a_match_inside_the_base_gate_wins_over_a_far_look_alike_of_the_widened_search():
    """With ``confirm_widened``: when the widened search's best pose lies outside the base gate but the scan
    also matches inside it (the estimate's own region), that match is applied, nothing is held."""
    env = _env(CONFIRM)
    sc = env.scanner
    true, cov, est = _widened(env, [0.05, 0.0, 0.0])
    far = est + np.array([0.0, 1.2, 0.0])  # a look-alike along a corridor, found only in the x8 region
    near = est + np.array([-0.04, 0.01, 0.01])
    assert not sc.in_gate(far, est, cov) and sc.in_gate(near, est, cov)
    calls = _stub_match(sc, far, near)
    assert _scan(env)[-1][1] == ACCEPTED and sc.held[0] is None and calls == [8.0, 1.0]
    np.testing.assert_allclose(env.pose_estimates()[0], near)
    # no match inside the base gate: the far one is held as before
    _widened(env, [0.05, 0.0, 0.0])
    calls = _stub_match(sc, far, None)
    assert _scan(env)[-1][1] == HELD and calls == [8.0, 1.0]
    np.testing.assert_array_equal(env.pose_estimates()[0], est)
    # the widened search's pose inside the base gate: no second search
    sc.held[0] = sc.held_from[0] = None
    calls = _stub_match(sc, near, far)
    assert _scan(env)[-1][1] == ACCEPTED and calls == [8.0]
    # no widening: one search; confirm_widened off: one search, the far pose applied
    calls = _stub_match(sc, None, None)
    assert sc.inflation[0] == 1.0 and _scan(env)[-1][1] == REJECTED and calls == [1.0]
    off = _env()
    _widened(off, [0.05, 0.0, 0.0])
    calls = _stub_match(off.scanner, far, near)
    assert _scan(off)[-1][1] == ACCEPTED and calls == [8.0]
    np.testing.assert_allclose(off.pose_estimates()[0], far)
