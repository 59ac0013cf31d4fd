"""The expert steers by its own route tracker on its belief, measures "off its route" from its progress
on, and a robot at its route's end with no informative place nearby drives farther back to scan
(issue 42: generated:201, 289, 314, 198; traces in ``docs/expert_benchmark.md``)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import parcover_env
from parcover_env.expert.scripted import route_from, route_length, route_upto, steer_point
from parcover_env.geometry import rotate, segments_blocked
from parcover_env.geometry.rays import point_segment_distance
from parcover_env.localization.sonar.service import HELD, UNINFORMATIVE

RELOCATE = {"observation": {"scan": {"enabled": True, "confirm_widened": True}},
            "expert": {"sonar_fix": {"relocate_distance": 0.5}}}


def _expert(seed: int):
    from parcover_env.expert import expert_for

    env = parcover_env.parallel_env(f"generated:{seed}", overrides=RELOCATE)
    expert = expert_for(env)
    obs, _ = env.reset(seed=seed)
    expert.reset(obs)
    return env, expert, obs


def test_route_from_cuts_the_polyline_at_an_arc_length():
    route = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 3.0]])
    np.testing.assert_allclose(route_from(route, 0.5), [[0.5, 0.0], [2.0, 0.0], [2.0, 3.0]])
    np.testing.assert_allclose(route_from(route, 2.0), [[2.0, 0.0], [2.0, 3.0]])  # at a vertex: from it
    np.testing.assert_allclose(route_from(route, 3.5), [[2.0, 1.5], [2.0, 3.0]])
    np.testing.assert_allclose(route_from(route, 9.0), [[2.0, 3.0], [2.0, 3.0]])  # past the end
    np.testing.assert_allclose(route_from(route, -1.0), route)
    assert route_length(route) == pytest.approx(5.0)


def test_off_route_is_measured_from_the_progress_on_so_a_goal_behind_a_wall_gives_way_to_a_seen_vertex():
    """generated:201, robot 5 (traced): coming back west along the corridor to its turn north at
    (3.03, 5.38) -> (3.08, 6.48), its progress jumped to the next leg (3.08, 6.48) -> (4.08, 6.78) in
    the room above; at (3.45, 5.77), 0.4 m from the leg it needs, its goal lay behind the room's wall."""
    env, expert, _ = _expert(201)
    route = env.mission.routes[5]
    np.testing.assert_allclose(route[3:6], [[3.03, 5.38], [3.08, 6.48], [4.08, 6.78]], atol=0.01)
    assert expert.cfg.off_route_distance == 0.5
    pose = np.array([3.45, 5.77, 1.08])
    expert.track.progress[5] = 5.29  # as traced, on the leg in the room
    goal = expert.track.goals()[5]
    np.testing.assert_allclose(goal, [4.06, 6.89], atol=0.02)
    rel = rotate(goal - pose[:2], -pose[2])
    out = expert._visible_goal(5, pose, rel)
    # its body (0.12 m + stop_margin 0.05 m) cannot drive straight to the turn (3.08, 6.48): the line passes
    # the door's east jamb (3.45, 5.97) at 0.094 m (until 2026-11-28 it steered there, by the centre line);
    # the latest route vertex it can drive straight to is the one before, (3.03, 5.38), below the door
    paths = expert._disc_paths()
    assert not paths.clear(pose[:2], route[4]) and paths.clear(pose[:2], route[3])
    line = np.c_[pose[None, :2], route[4][None]]
    assert float(point_segment_distance(np.array([[3.45, 5.97]]), line).min()) == pytest.approx(0.094, abs=1e-3)
    np.testing.assert_allclose(out, rotate(route[3] - pose[:2], -pose[2]), atol=1e-9)
    # there, the turn through the door (x 2.61-3.45) is in reach of its body
    there = np.array([*route[3], 2.0])
    np.testing.assert_allclose(expert._visible_goal(5, there, rotate(goal - route[3], -2.0)),
                               rotate(route[4] - route[3], -2.0), atol=1e-9)
    # measured from the whole route (0.4 m from the leg it needs) the goal behind the wall stood
    track, expert.track = expert.track, None
    np.testing.assert_allclose(expert._visible_goal(5, pose, rel), rel)
    expert.track = track
    # progress still on the leg it needs (before the jump): its goal is in sight, unchanged
    expert.track.progress[5] = 3.49
    rel = rotate(expert.track.goals()[5] - pose[:2], -pose[2])
    np.testing.assert_allclose(expert._visible_goal(5, pose, rel), rel)


def test_a_robot_whose_body_would_graze_a_wall_on_the_way_to_its_goal_takes_the_disc_path():
    """generated:18, robot 4 (traced; also 7190): a follower carried 4.5 m past its turn, promoted in the door
    gap at the corridor's top wall (y 7.53, x 6.39-7.51), its belief right; the line to its goal 4.4 m west
    ran a few cm below the wall's face: the front sonar braked it, it backed off and drove in again from
    43 s to the episode's end. Now it steers by the shortest path of its body plus ``stop_margin`` (0.17 m)."""
    env, expert, _ = _expert(18)
    walls = env.mission.known_map.segments
    assert expert.stop == pytest.approx(0.17) and env.scenario.robot.radius == 0.12
    expert.track.progress[4] = 3.49  # as traced: the leg north at x = 3.2-3.3
    goal = expert.track.goals()[4]
    np.testing.assert_allclose(goal, [3.243, 7.498], atol=1e-3)
    pose = np.array([7.65, 7.50, math.radians(-174.0)])
    rel = rotate(goal - pose[:2], -pose[2])
    # the centre line is in sight of the goal (what was tested), 0.03 m below the jamb's corner (7.51, 7.53)
    assert not segments_blocked(pose[None, :2], goal[None], walls)[0]
    line = np.c_[pose[None, :2], goal[None]]
    assert float(point_segment_distance(np.array([[7.51, 7.53]]), line).min()) == pytest.approx(0.030, abs=1e-3)
    out = expert._visible_goal(4, pose, rel)
    target = pose[:2] + rotate(out, pose[2])
    # down into the corridor first, away from the wall's face: not the straight line west
    assert target[1] < 7.40 and abs(target[0] - pose[0]) < 0.06
    way = expert._disc_paths().path(pose[:2], goal)
    np.testing.assert_allclose(target, steer_point(way, pose[:2], 0.12), atol=1e-12)
    clearance = np.array([float(point_segment_distance(p[None], walls).min()) for p in way[:-1]])
    np.testing.assert_allclose(clearance, 0.17, atol=2e-4)  # it bends round corners at 0.17 m
    long = np.flatnonzero(np.hypot(*np.diff(way, axis=0).T) > 1.0)  # one straight leg west along the corridor
    np.testing.assert_allclose(way[[long[0], long[0] + 1]], [[7.51, 7.36], [3.65, 7.36]], atol=1e-9)
    # on its route (within off_route_distance) it steers by its route as before
    near = np.array([6.08, 7.30, math.pi])
    rel = rotate(expert.track.goals()[4] - near[:2], -near[2])
    np.testing.assert_allclose(expert._visible_goal(4, near, rel), rel)


def test_steer_point_is_the_first_vertex_beyond_the_reach():
    way = np.array([[0.0, 0.0], [0.05, 0.0], [0.3, 0.0], [0.3, 1.0]])
    np.testing.assert_allclose(steer_point(way, np.zeros(2), 0.12), [0.3, 0.0])
    np.testing.assert_allclose(steer_point(way, np.array([0.3, 0.95]), 0.12), [0.3, 1.0])  # the last one
    np.testing.assert_allclose(steer_point(way, np.array([0.3, 0.5]), 0.12), [0.0, 0.0])


def test_the_goal_is_the_experts_own_tracker_point_also_without_a_correction():
    """generated:289 and 314 (traced): a promoted follower, its env estimate 0.6-1.3 m off while it
    followed, the env's progress stalled or on another leg; after the env's fix it steered by the
    env's goal into a wall, while its own tracker (on its chained belief) had the right one."""
    env, expert, obs = _expert(3)
    a = "robot_0"
    assert not expert.fixer.corrected(a)
    for i in range(len(obs)):  # the poses it steers by: the observed estimates (no correction)
        expert._last_odom[i] = expert._odom(obs[f"robot_{i}"])
    bel = expert.belief()
    env_goal = np.array([env.layout.get(obs[a], k)[0] for k in ("goal_dx", "goal_dy")])
    expert.track.progress[0] = 4.0  # its own progress differs from the env's (0 m, at the start)
    want = rotate(expert.track.goals()[0] - bel[0, :2], -bel[0, 2])
    got = expert._goal(obs[a], a, bel)
    np.testing.assert_allclose(got, want, atol=1e-9)
    assert np.hypot(*(got - env_goal)) > 1.0
    # without sonar fixes (no tracker of its own) the observed goal is used
    assert np.allclose(expert._goal(obs[a], a, None), env_goal, atol=1e-6)


def test_the_pose_check_before_a_kpoi_reads_the_experts_own_goal():
    env, expert, obs = _expert(3)
    a = "robot_0"
    kpois = env.mission.kpois
    np.testing.assert_allclose(env.mission.routes[0][-1], [2.58, 0.32], atol=0.01)
    np.testing.assert_allclose(kpois[2], [2.59, 0.35], atol=0.01)
    odom = np.array([3.0, 0.6, math.pi])
    assert expert._kpoi_check(a, obs[a], odom) is None  # its progress at the start: no KPOI ahead
    expert.track.progress[0] = 9.0  # 0.39 m before its route's end, the KPOI
    assert np.hypot(*(expert.track.goals()[0] - odom[:2])) <= expert.cfg.sonar_fix.kpoi_check_distance
    assert expert._kpoi_check(a, obs[a], odom) == 2


def _relocating_at_start(behind):
    """generated:3's robot 0 after an uninformative env scan, the place prediction stubbed: 0.7 m ahead,
    ``behind(near, far)`` back from the route's end."""
    from test_scan_elsewhere import _after_scan

    env, expert, _ = _expert(3)
    route = env.mission.routes[0]
    _after_scan(expert.fixer, UNINFORMATIVE)
    expert.fixer.states["robot_0"].move = None
    expert.places = SimpleNamespace(ahead=lambda *args: 0.7, behind_at=lambda r, xy, near, far: behind(near, far))
    return expert, route


def test_at_its_route_end_with_no_informative_place_within_rescan_distance_it_drives_farther_back():
    """generated:198, robot 1 (traced): at its route's end by the wall of an open room every scan was
    uninformative, and no place 0.5-2 m back was predicted informative: it stood there 190 s, 0.48 m
    from its KPOI. Now it drives back to the first predicted place farther along its route in sight."""
    far_place = np.array([7.2, 4.9])
    calls = []

    def behind(near, far):
        calls.append((near, far))
        return (far_place, 3.1) if near >= 2.0 else None

    expert, route = _relocating_at_start(behind)
    end = np.array([route[-1][0], route[-1][1], 0.0])
    expert._relocate("robot_0", 0, end, True, np.full(16, 2.5))
    length = route_length(route)
    assert calls == [(0.5, 2.0), (2.0, pytest.approx(length))]
    np.testing.assert_array_equal(expert.detours["robot_0"], far_place)
    assert expert.fixer.states["robot_0"].move == math.inf  # scans on arrival
    assert expert.back["robot_0"] == 3.1
    # its scan there is uninformative too (no fix): back at its route's end, the next place is farther back
    from test_scan_elsewhere import _scan_again

    _scan_again(expert.fixer, UNINFORMATIVE)
    expert.fixer.states["robot_0"].move = None
    expert.detours.clear()
    calls.clear()
    expert._relocate("robot_0", 0, end, True, np.full(16, 2.5))
    assert calls == [(pytest.approx(3.6), pytest.approx(3.6))]  # 3.1 + relocate_distance 0.5 on
    np.testing.assert_array_equal(expert.detours["robot_0"], far_place)
    # a fix ends it: the next time from 0.5 m back again
    expert.fixer.step("robot_0", np.array([1.0, 1.0, 0.0]), 0.0, 0.0, np.full(len(expert.fixer.beams), 1.0), True)
    assert not expert.fixer.relocating("robot_0")
    expert._relocate("robot_0", 0, end, True, np.full(16, 2.5))
    assert "robot_0" not in expert.back
    # nothing in sight at all: it stands (as before)
    expert, route = _relocating_at_start(lambda near, far: None)
    expert._relocate("robot_0", 0, end, True, np.full(16, 2.5))
    assert "robot_0" not in expert.detours and expert.fixer.states["robot_0"].move == math.inf


def test_a_robot_reaching_its_route_end_before_the_place_chosen_ahead_chooses_again():
    """generated:314 (re-run), robot 1: spaced scans in an open room, the next one due 2 m on, but its
    route ended before: it never scanned again. At its route's end the choice is made again."""
    place = np.array([7.8, 8.0])
    expert, route = _relocating_at_start(lambda near, far: (place, 0.5))
    start = np.array([route[0][0], route[0][1], 0.0])
    expert._relocate("robot_0", 0, start, False, np.full(16, 2.5))
    assert expert.fixer.waiting_distance("robot_0") == pytest.approx(0.7)  # the place ahead
    end = np.array([route[-1][0], route[-1][1], 0.0])
    expert._relocate("robot_0", 0, end, True, np.full(16, 2.5))
    np.testing.assert_array_equal(expert.detours["robot_0"], place)
    assert expert.fixer.waiting_distance("robot_0") == math.inf
    expert._relocate("robot_0", 0, end, True, np.full(16, 2.5))  # chosen at the end: kept
    np.testing.assert_array_equal(expert.detours["robot_0"], place)
    assert expert.fixer.waiting_distance("robot_0") == math.inf
    expert.fixer.choose_again("robot_0")
    assert expert.fixer.needs_place("robot_0")


def test_route_upto_ends_at_the_kpoi_vertex_the_robot_heads_for():
    route = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [2.0, 0.0], [4.0, 0.0]])  # out and back to (2, 1)
    np.testing.assert_allclose(route_upto(route, 0.5, np.array([2.05, 0.98]), 0.1), route[:3])
    # progress past (2, 0) once: the next visit of (2, 0) is the one it heads for
    np.testing.assert_allclose(route_upto(route, 2.5, np.array([2.0, 0.0]), 0.1), route[:4])
    assert route_upto(route, 0.5, np.array([3.0, 3.0]), 0.1) is None
    assert route_upto(route, 4.5, np.array([2.0, 1.0]), 0.1) is None  # passed


def test_after_an_uninformative_pose_check_before_a_kpoi_it_scans_from_a_place_behind_first():
    """generated:7018, robot 3 (traced): its pose check 0.43 m before the KPOI (7.48, 0.35), at the end of an
    out-and-back leg, was uninformative (its belief 0.41 m off); with spaced scans (the known map's
    predictions had failed there) its next scan was 2 m on, and it went on to the KPOI on that belief, never
    nearer than 0.48 m. Now it first drives back along its route to a place predicted informative, as at
    its route's end, and scans there on arrival."""
    from parcover_env.expert.sonar_fix import _State

    env, expert, _ = _expert(7018)
    a, route, kpoi = "robot_3", env.mission.routes[3], env.mission.kpois[5]
    np.testing.assert_allclose(route[4:8], [[6.48, 1.72], [7.48, 1.68], [7.48, 0.32], [7.48, 1.68]], atol=0.01)
    np.testing.assert_allclose(kpoi, [7.48, 0.35], atol=0.01)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(route, axis=0).T))])
    expert.track.progress[3] = arc[5] + 0.93  # at (7.48, 0.75), as traced
    odom = np.array([7.47, 0.75, -math.pi / 2])

    def relocating() -> None:
        expert.fixer.states[a] = _State(np.zeros(3), np.eye(3) * 1e-3, last_odom=odom.copy(), relocate=True,
                                        uninformative=2, spaced=True, driven_since_scan=0.0)

    relocating()  # without a check before the KPOI: spaced scans, 2 m on (as before)
    expert._relocate(a, 3, odom, False, np.full(16, 2.5))
    assert a not in expert.detours and expert.fixer.waiting_distance(a) == pytest.approx(2.0)
    relocating()
    expert.checking[a] = kpoi
    upto = route_upto(route, float(expert.track.progress[3]), kpoi, env.mission.waypoint_tol)
    np.testing.assert_array_equal(upto, route[:7])
    expert._relocate(a, 3, odom, False, np.full(16, 2.5))
    # nothing predicted informative 0.5-2 m back from the KPOI (the leg's corridor): farther back, 2.52 m,
    # just round the corner into the corridor above (the place of the trace)
    np.testing.assert_allclose(expert.detours[a], [6.475, 1.874], atol=1e-3)
    assert expert.back[a] == pytest.approx(2.5, abs=0.05)
    assert expert.fixer.waiting_distance(a) == math.inf  # it scans there on arrival, not before
    assert expert.places.informative(np.array([*expert.detours[a], math.pi / 2]))
    # the robot steers for that place, not for the KPOI
    bel = np.array([odom])
    np.testing.assert_allclose(expert._goal(None, a, np.repeat(bel, 4, axis=0)),
                               rotate(expert.detours[a] - odom[:2], -odom[2]), atol=1e-12)
    # a fix ends it
    expert.fixer.states[a].relocate = False
    expert._relocate(a, 3, odom, False, np.full(16, 2.5))
    assert a not in expert.checking and a not in expert.detours and a not in expert.back


def test_a_held_scan_whose_place_ahead_is_its_route_end_0_m_on_drives_back_instead_of_rescanning_in_place():
    """generated:7061, robot 3 (traced): its tracked progress at its route's end, its belief beyond
    ``waypoint_tol`` of it, a held scan: the place ahead was its route's end, 0 m on, so the next scan was
    due at once, where it stood: the held scan repeated in place six times (98-104 s). A place ahead nearer
    than ``relocate_distance`` is chosen as at the route's end: back along the route, else on at least
    ``relocate_distance``."""
    from test_scan_elsewhere import _scan_again

    place = np.array([1.2, 0.4])
    calls = []

    def behind(near, far):
        calls.append((near, far))
        return place, 0.6

    expert, route = _relocating_at_start(behind)
    _scan_again(expert.fixer, HELD)
    expert.fixer.states["robot_0"].move = None
    assert expert.fixer.held("robot_0") and not expert.fixer.spaced("robot_0")
    pose = np.array([route[0][0], route[0][1], 0.0])
    ranges = np.full(16, 2.5)
    expert.places.ahead = lambda *args: 0.0
    expert._relocate("robot_0", 0, pose, False, ranges)
    assert calls == [(0.5, 2.0)]
    np.testing.assert_array_equal(expert.detours["robot_0"], place)
    assert expert.fixer.waiting_distance("robot_0") == math.inf  # on arrival there, not where it stands
    # nothing back along its route in sight: on at least relocate_distance (0.5 m), not 0
    expert, route = _relocating_at_start(lambda near, far: None)
    _scan_again(expert.fixer, HELD)
    expert.fixer.states["robot_0"].move = None
    expert.places.ahead = lambda *args: 0.3
    expert._relocate("robot_0", 0, pose, False, ranges)
    assert "robot_0" not in expert.detours
    assert expert.fixer.waiting_distance("robot_0") == pytest.approx(0.5)
    # a place ahead at relocate_distance or farther is kept as it is
    expert, route = _relocating_at_start(lambda near, far: None)
    _scan_again(expert.fixer, HELD)
    expert.fixer.states["robot_0"].move = None
    expert.places.ahead = lambda *args: 0.5
    expert._relocate("robot_0", 0, pose, False, ranges)
    assert expert.fixer.waiting_distance("robot_0") == pytest.approx(0.5)


def test_a_promoted_follower_with_a_chained_belief_checks_its_pose_before_a_kpoi_with_the_envs_scans():
    """With the env's scans the only correction on a belief is a follower's camera chain, never checked by a
    scan: a promoted follower reached its KPOI on it unchecked (``_kpoi_check`` skipped any corrected robot).
    The expert's own sonar fixes (``localization: both``) still need no check."""
    env, expert, obs = _expert(3)
    a = "robot_0"
    odom = np.array([3.0, 0.6, math.pi])
    expert.track.progress[0] = 9.0  # 0.39 m before its route's end, the KPOI 2
    chained = np.array([0.0, 0.0, 0.01])  # its belief carries a chained correction
    expert.fixer.relative_update(a, odom, odom + chained, np.eye(3) * 1e-6)
    assert expert.fixer.corrected(a) and expert.fixer.env_scan
    assert expert._kpoi_check(a, obs[a], odom) == 2
    expert.fixer.env_scan = False  # its own sonar fix corrects it: no check
    assert expert._kpoi_check(a, obs[a], odom) is None
    expert.fixer.states.clear()  # uncorrected: checked either way
    assert expert._kpoi_check(a, obs[a], odom) == 2
