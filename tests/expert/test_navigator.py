"""SonarNavigator (seed B Fig. 1) on the env: interface, belief algebra, scan + localize, hallway mission."""

from __future__ import annotations

import math

import numpy as np
import pytest

import parcover_env
from parcover_env.expert.config import NavigatorConfig
from parcover_env.expert.navigator import SonarNavigator
from parcover_env.geometry import wrap_angle as wrap
from parcover_env.geometry.poses import compose as _compose
from parcover_env.geometry.poses import inverse as _inverse
from parcover_env.harness.rollout import run_episode
from parcover_env.localization.sonar.parallel_paths import lateral_offset


def test_pose_algebra_roundtrip():
    a, b = np.array([1.0, -2.0, 0.7]), np.array([0.3, 0.4, -2.0])
    assert np.allclose(_compose(_inverse(a), a), 0.0, atol=1e-12)
    # the correction f o^-1 maps the odometry pose o onto the fix f
    assert np.allclose(_compose(_compose(b, _inverse(a)), a), b)


def test_interface_and_actions_in_range():
    env = parcover_env.parallel_env("hallway")
    nav = SonarNavigator.for_env(env)
    obs, _ = env.reset(seed=1)
    nav.reset(obs)
    for _ in range(5):
        act = nav.act(obs)
        assert set(act) == set(obs)
        for a in act.values():
            assert a.shape == (2,) and a.dtype == np.float32 and np.all(np.abs(a) <= 1.0)
        obs, *_ = env.step(act)
    assert nav.phase == "drive"
    assert nav.subgoals().shape == (2, 2)
    assert nav.belief().shape == (2, 3)
    assert set(nav.stats()) >= {"sonar_scans", "sonar_localized", "sonar_failed", "sonar_mean_correction"}


def test_bad_inputs_raise():
    env = parcover_env.parallel_env("t_room", overrides={"observation": {"sonar": False}})
    with pytest.raises(ValueError, match="sonar"):
        SonarNavigator.for_env(env)
    with pytest.raises(ValueError, match="max_axis"):
        NavigatorConfig(max_axis=0.0)


def test_scan_in_place_localizes_and_corrects_the_belief():
    env = parcover_env.parallel_env("t_room")
    nav = SonarNavigator.for_env(env)
    obs, _ = env.reset(seed=3)
    nav.reset(obs)
    nav.act(obs)  # builds paths and plans
    # corrupt the belief by 12 cm / 3 deg, then force a scan where the robot stands
    nav.correction[0] = np.array([0.12, -0.05, math.radians(3)])
    nav.axis0[0] = 0.2
    nav.phase, nav.queue, nav.scan = "scan", [0], None
    start = env.world.poses()[0].copy()
    for _ in range(200):
        obs, *_ = env.step(nav.act(obs))
        if nav.fixes:
            break
    assert nav.fixes and nav.fixes[0]["success"]
    true = env.world.poses()[0]
    assert np.hypot(*(true[:2] - start[:2])) < 0.03  # turned in place
    assert abs(true[2] - start[2]) < 2 * math.pi  # at most one turn
    bel = nav.belief()[0]
    assert np.hypot(*(bel[:2] - true[:2])) < 0.05
    assert abs(math.remainder(bel[2] - true[2], 2 * math.pi)) < math.radians(3)
    assert nav.stats()["sonar_localized"] == 1


def test_hallway_mission_completes_with_sonar_navigator():
    """Seed B's two-robot mechanism in a real mission: the robots drive side by side on parallel paths
    (lanes 2 r + slow_margin = 0.58 m apart in the 2 m corridors), and subgoals of robots that block
    each other's scans are rearranged; the lateral offset is checked against the true poses too."""
    env = parcover_env.parallel_env("hallway")
    nav = SonarNavigator.for_env(env)
    obs, _ = env.reset(seed=0)
    nav.reset(obs)
    lateral = []
    while env.agents:
        obs, *_ = env.step(nav.act(obs))
        v = [abs(float(nav.layout.get(o, "v")[0])) for o in obs.values()]
        if nav.phase == "drive" and len(v) == 2 and min(v) > nav.p.stop_speed and not nav.arrived.any():
            true = env.world.poses()
            lateral.append(lateral_offset(true[:, :2], true[:, 2]))
    m = env.metrics.summary()
    m.update(nav.stats())
    assert m["success"] and m["kpois_visited"] == 2
    assert m["sonar_scans"] >= 4 and m["sonar_localized"] >= 2
    bel, true = nav.belief(), env.world.poses()
    assert np.hypot(*(bel[:, :2] - true[:, :2]).T).max() < 0.15
    assert m["sonar_rearranged"] > 0
    assert np.median(lateral) >= 0.3 and m["sonar_lateral_offset"] >= 0.3
    assert abs(np.median(lateral) - m["sonar_lateral_offset"]) < 0.05
    assert m["sonar_bias_subgoals"] > 0 and m["sonar_bias_after_deg"] <= m["sonar_bias_before_deg"]


def test_navigator_takes_its_tunables_from_the_scenario():
    over = {"expert": {"navigator": {"max_axis": 0.2, "front_sector_deg": 50.0}}}
    nav = SonarNavigator.for_env(parcover_env.parallel_env("hallway", overrides=over))
    default = SonarNavigator.for_env(parcover_env.parallel_env("hallway"))
    assert nav.p.max_axis == 0.2 and default.p.max_axis == NavigatorConfig().max_axis
    assert 0 < len(default.front) < len(nav.front)


def test_navigator_rearranges_a_blocked_pair_at_the_hallways_far_end():
    """§3.2 in the navigator: near the hallway's far end, on their parallel paths, robot 0 stands in
    the angle robot 1 needs to scan the corner eq. 1 chose for it (both in one relaxed sector); the
    pair's subgoals move so that the worse of their unblocked scan angles of that corner grows, they
    stay apart and inside their windows. A pair far apart keeps its subgoals."""
    from parcover_env.localization.sonar.subgoals import unblocked_scan_angle

    env = parcover_env.parallel_env("hallway", preset="ideal")
    nav = SonarNavigator.for_env(env)
    obs, _ = env.reset(seed=0)
    nav.reset(obs)
    targets = np.array([14.5, 14.0])
    ends = np.array([p.s[-1] for p in nav.paths])
    windows = np.stack([targets - 0.5, np.minimum(targets + 2.5, ends)], axis=1)
    args = (nav.radius, nav.sonar_cfg.range_max, nav.incidence, nav.cone)
    before = np.array([p.point(t) for p, t in zip(nav.paths, targets, strict=True)])
    f = nav.features[int(nav.scores[1].feature[nav.paths[1].index(targets[1])])]
    assert nav.rearranger.sector_of(before[0]) == nav.rearranger.sector_of(before[1]) >= 0

    def worst(pts):
        return min(unblocked_scan_angle(pts[i], f, pts[[1 - i]], *args) for i in range(2))

    blocked = unblocked_scan_angle(before[1], f, before[[0]], *args)
    assert blocked < unblocked_scan_angle(before[1], f, np.zeros((0, 2)), *args) - math.radians(10)
    res = nav.rearranger.rearrange(nav.paths, nav.scores, targets.copy(), windows, np.arange(2))
    after = np.where(np.isfinite(res.goals), res.goals,
                     np.array([p.point(t) for p, t in zip(nav.paths, res.targets, strict=True)]))
    assert res.pairs == 1
    assert np.hypot(*(after[0] - after[1])) >= 2 * nav.radius + nav.p.separation_margin - 1e-9
    assert nav.rearranger.free(after).all()
    assert worst(after) > worst(before) + math.radians(10)
    assert np.all(res.targets >= windows[:, 0] - 1e-9) and np.all(res.targets <= windows[:, 1] + 1e-9)
    far = np.array([3.0, 2.5])
    res = nav.rearranger.rearrange(nav.paths, nav.scores, far.copy(), np.stack([far - 0.5, far + 2.5], 1),
                                   np.arange(2))
    assert np.array_equal(res.targets, far) and res.pairs == 0 and not np.isfinite(res.goals).any()


def test_localization_region_holds_the_seed_b_circle_and_the_covariance_ellipse():
    env = parcover_env.parallel_env("hallway")
    nav = SonarNavigator.for_env(env)
    obs, _ = env.reset(seed=1)
    nav.reset(obs)
    circle = max(nav.ellipse(0).axes)  # initial_axis at the start
    assert circle == pytest.approx(nav.p.initial_axis)
    k = nav.p.region_sigmas
    nav.cov[0] = np.diag([0.4**2, 0.01**2, 0.0])  # thin along x: 0.4 m sigma along x, 1 cm across
    e = nav.region(0, (1.0, 1.0))
    assert e.axes[0] == pytest.approx(np.sqrt((k * 0.4) ** 2 + circle**2))  # major: k sigma, widened
    assert e.axes[1] == pytest.approx(np.sqrt((k * 0.01) ** 2 + circle**2))  # minor: about the circle
    assert abs(math.remainder(e.angle, math.pi)) < 1e-9
    # driving straight (along x from the start pose) grows the covariance from the fix's
    nav.cov[0] = nav.fix_cov
    start = nav.cov[0].copy()
    for _ in range(20):
        obs, *_ = env.step({a: np.array([1.0, 0.0], dtype=np.float32) for a in env.agents})
        nav._ingest(obs)
    assert nav.cov[0, 0, 0] > start[0, 0] and nav.cov[0, 2, 2] > start[2, 2]


def _hallway_nav():
    env = parcover_env.parallel_env("hallway", preset="ideal")
    nav = SonarNavigator.for_env(env)
    obs, _ = env.reset(seed=0)
    nav.reset(obs)
    return nav


def test_lane_holds_teammates_ahead_within_two_radii_plus_the_stop_margin():
    nav = _hallway_nav()
    r, lane = nav.radius, 2 * nav.radius + nav.p.stop_margin  # 0.165 m, 0.38 m
    bel = np.array([[0.0, 0.0, 0.0], [1.0, 0.3, 0.0]])
    gap, j = nav._lane(0, bel, 0.0)
    assert j == 1 and gap == pytest.approx(math.hypot(1.0, 0.3) - 2 * r)
    assert nav._lane(0, bel, math.pi) == (math.inf, -1)  # behind
    bel[1] = [1.0, lane + 0.01, 0.0]
    assert nav._lane(0, bel, 0.0) == (math.inf, -1)  # beside the lane
    assert nav._lane(0, bel, math.atan2(lane + 0.01, 1.0))[1] == 1  # heading at it
    bel[1] = [0.0, -0.5, 0.0]
    assert nav._lane(0, bel, -math.pi / 2)[0] == pytest.approx(0.5 - 2 * r)


def test_team_brake_slows_for_the_lane_only():
    nav = _hallway_nav()
    r, stop, slow = nav.radius, nav.p.stop_margin, nav.p.slow_margin
    ahead = 2 * r + stop + 0.5 * (slow - stop)  # halfway between the stop and slow distances
    bel = np.array([[0.0, 0.0, 0.0], [ahead, 0.0, math.pi]])
    assert nav._team_brake(0, bel) == pytest.approx(0.5)
    assert nav._team_brake(1, bel) == pytest.approx(0.5)
    bel[1] = [2 * r + stop - 0.01, 0.0, 0.0]
    assert nav._team_brake(0, bel) == 0.0
    bel[1] = [2 * r + slow + 0.01, 0.0, 0.0]
    assert nav._team_brake(0, bel) == 1.0
    bel[1] = [0.3, 2 * r + stop + 0.01, 0.0]  # close, but beside the lane
    assert nav._team_brake(0, bel) == 1.0


def test_bypass_passes_a_teammate_that_will_not_move():
    nav = _hallway_nav()
    r = nav.radius
    # hallway seed 49: robot 0 is done at its KPOI, robot 1 stands south of it and must go east past it
    bel = np.array([[9.96, 6.92, 0.0], [9.88, 6.56, 0.38]])
    d = np.array([10.675, 6.875]) - bel[1, :2]
    assert nav._lane(1, bel, math.atan2(d[1], d[0]))[1] == 0
    assert np.array_equal(nav._bypass(1, bel, d), d)  # robot 0 still driving: wait behind it
    nav.done[0] = True
    out = nav._bypass(1, bel, d)
    phi = math.atan2(0.36, 0.08)
    assert math.atan2(out[1], out[0]) == pytest.approx(phi - math.pi / 2)  # sideways, on d's side
    assert np.hypot(*out) == pytest.approx(np.hypot(*d))
    assert nav._lane(1, bel, math.atan2(out[1], out[0])) == (math.inf, -1)
    # an arrived teammate farther than the stop distance: brake, no bypass; on the other side of d,
    # the other side
    nav.done[0], nav.arrived[0] = False, True
    bel = np.array([[0.0, 0.0, 0.0], [-(2 * r + nav.p.stop_margin + 0.01), 0.0, 0.0]])
    d = np.array([2.0, 0.1])
    assert np.array_equal(nav._bypass(1, bel, d), d)
    bel[1, 0] += 0.02
    assert math.atan2(*nav._bypass(1, bel, d)[::-1]) == pytest.approx(math.pi / 2)
    assert math.atan2(*nav._bypass(1, bel, np.array([2.0, -0.1]))[::-1]) == pytest.approx(-math.pi / 2)


def test_bypass_breaks_a_mutual_block():
    """Hallway seed 47: at the routes' ends robot 1 stands 0.34 m beside robot 0's westward heading
    (inside its lane of 0.38 m) and robot 0 stands in robot 1's lane: each brakes for the other, and
    each heads sideways, away from the other, on the side nearer to its way."""
    nav = _hallway_nav()
    bel = np.array([[10.26, 6.83, 3.06], [10.10, 6.50, 0.56]])
    assert nav._team_brake(0, bel) == 0.0 and nav._team_brake(1, bel) == 0.0
    d0, d1 = np.array([9.875, 6.875]) - bel[0, :2], np.array([10.675, 6.875]) - bel[1, :2]
    rel = bel[1, :2] - bel[0, :2]
    phi = math.atan2(rel[1], rel[0])
    out0, out1 = nav._bypass(0, bel, d0), nav._bypass(1, bel, d1)
    assert math.atan2(out0[1], out0[0]) == pytest.approx(wrap(phi - math.pi / 2))
    assert math.atan2(out1[1], out1[0]) == pytest.approx(wrap(phi + math.pi - math.pi / 2))
    bel[0, 2] = 0.0  # robot 0 heads away from robot 1: robot 1 waits behind it, no bypass
    assert np.array_equal(nav._bypass(1, bel, d1), d1)


@pytest.mark.parametrize("seed", [11, 49])
def test_hallway_crossings_at_the_routes_ends_complete(seed):
    """Seed 11: the two robots stood in each other's lanes at the routes' ends; seed 49: robot 1 had to
    pass robot 0 that was done at its KPOI. Both stalled before the lane and the bypass."""
    env = parcover_env.parallel_env("hallway")
    m = run_episode(env, SonarNavigator.for_env(env), seed=seed)
    assert m["success"] and m["kpois_visited"] == 2


def test_side_turn_steers_away_from_a_close_side_echo():
    nav = _hallway_nav()  # AmigoBot ring: side beams at +-90 deg only (the +-44 deg beams are 46 deg off)
    assert np.degrees(nav.beams[nav.side]).round().tolist() == [90.0, -90.0]
    stop, slow = nav.radius + nav.p.stop_margin, nav.radius + nav.p.slow_margin
    obs = np.zeros(nav.layout.size, dtype=np.float32)
    sonar = nav.layout.slices["sonar"]

    def turn(left, right, front=2.54):
        ranges = np.full(len(nav.beams), front)
        ranges[0], ranges[5] = left, right  # +90 deg, -90 deg
        obs[sonar] = ranges
        return nav._side_turn(obs)

    assert turn(2.54, 2.54) == 0.0
    assert turn(slow + 0.01, 2.54) == 0.0
    mid = 0.5 * (stop + slow)
    assert turn(mid, 2.54) == pytest.approx(-0.5 * nav.w_max, rel=1e-5)  # wall on the left: turn right
    assert turn(2.54, mid) == pytest.approx(0.5 * nav.w_max, rel=1e-5)
    assert turn(2.54, stop - 0.02) == pytest.approx(nav.w_max)
    assert turn(mid, stop) == pytest.approx(nav.w_max)  # the nearer echo wins
    assert turn(2.54, 2.54, front=0.1) == 0.0  # front beams are the brake's business
    nav.side = np.zeros(0, dtype=int)  # a ring without side beams never turns
    assert turn(0.1, 0.1) == 0.0


def test_odometry_beyond_the_observation_bounds_is_dead_reckoned_from_the_encoder_speed():
    """The observed x, y are clipped to the map box +- 1 m; a drifted odometry pose beyond it moves by
    v dt along the mid-step heading (0.3 m/s x 0.1 s along +x, then at 45 deg during a quarter turn),
    and keeps its offset to the reading once the reading is inside again."""
    env = parcover_env.parallel_env("hallway", preset="ideal")
    nav = SonarNavigator.for_env(env)
    obs, _ = env.reset(seed=0)
    nav.reset(obs)
    lay, o, dt = nav.layout, obs["robot_0"], nav.dt
    hi_x = float(lay.high[lay.slices["x"]][0])
    o[lay.slices["x"]], o[lay.slices["v"]] = hi_x, 0.3
    o[lay.slices["cos_theta"]], o[lay.slices["sin_theta"]] = 1.0, 0.0
    nav._ingest(obs)
    x0, y0 = nav.last_odom[0, :2]
    nav._ingest(obs)
    assert nav.last_odom[0, :2] == pytest.approx([x0 + 0.3 * dt, y0])
    o[lay.slices["cos_theta"]], o[lay.slices["sin_theta"]] = 0.0, 1.0
    nav._ingest(obs)
    step = 0.3 * dt / math.sqrt(2)
    assert nav.last_odom[0, :2] == pytest.approx([x0 + 0.3 * dt + step, y0 + step])
    o[lay.slices["x"]] = hi_x - 0.5
    nav._ingest(obs)  # the step off the bound is still dead-reckoned (the last reading was clipped)
    after = nav.last_odom[0, :2].copy()
    assert after == pytest.approx([x0 + 0.3 * dt + step, y0 + step + 0.3 * dt])
    o[lay.slices["x"]] += 0.01
    o[lay.slices["y"]] += 0.02
    nav._ingest(obs)  # inside: the observed motion
    assert nav.last_odom[0, :2] == pytest.approx(after + [0.01, 0.02], abs=1e-6)
