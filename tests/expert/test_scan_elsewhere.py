"""After a held or uninformative env scan the expert scans next from elsewhere: where the known map
predicts an informative scan (``expert/scan_places.py``), never again where it stands."""

from __future__ import annotations

import math

import numpy as np
import pytest

import parcover_env
from parcover_env.config.schema import MapConfig
from parcover_env.expert.scan_places import ScanPlaces
from parcover_env.localization.sonar.known_map import known_map_features
from parcover_env.localization.sonar.service import ACCEPTED, HELD, REJECTED, UNINFORMATIVE


def _corridor_places():
    """A 12 x 1.2 m corridor (sonar range 2.5 m, shift test 0.2 m / 0.003 m)."""
    sc = parcover_env.load_scenario("generated:120")
    assert sc.robot.sonar.range_max == 2.5
    assert (sc.observation.scan.shift_test, sc.observation.scan.min_shift_increase) == (0.2, 0.003)
    segments = known_map_features(MapConfig(size=(12.0, 1.2)), sc.robot.sonar.range_max)[0].segments
    return ScanPlaces(sc, segments)


def test_a_scan_is_predicted_informative_only_within_sonar_range_of_a_corridor_end():
    places = _corridor_places()
    informative = {x: places.informative(np.array([x, 0.6, 0.0])) for x in (0.5, 2.0, 3.0, 6.0, 9.0, 10.0, 11.5)}
    # the end walls at x = 0 and 12 are seen within 2.5 m: shifted along the corridor the scan changes
    assert informative == {0.5: True, 2.0: True, 3.0: False, 6.0: False, 9.0: False, 10.0: True, 11.5: True}
    assert places.informative(np.array([6.0, 0.6, 1.0])) is False  # whatever the heading
    assert places.informative(np.array([2.0, 0.6, 1.0])) is True
    # the service's trimmed error decides: near the edge of range (x = 2.45) the untrimmed error would
    # still rise by 0.006 m under the shifts, the best 90 % of the readings only by 0.0016 m < 0.003 m
    assert places.informative(np.array([2.45, 0.6, 0.0])) is False
    np.testing.assert_allclose(places.angles, np.radians(np.arange(0.0, 360.0, 5.0)))  # the env's scan, 5 deg
    places.step = 0.0  # shift test off: every scan passes, even mid-corridor
    assert places.informative(np.array([6.0, 0.6, 0.0])) is True


def test_the_next_scan_place_ahead_is_where_the_end_wall_comes_in_range():
    places = _corridor_places()
    route = np.array([[3.0, 0.6], [11.5, 0.6]])
    # from x = 9 (progress 6 m): the first informative place at least 0.5 m on is x = 9.6 (2.4 m from the wall)
    assert places.ahead(route, 6.0, 0.5, 2.0) == pytest.approx(0.6)
    assert places.ahead(route, 0.0, 0.5, 2.0) is None  # x 3.5-5: the middle of the corridor
    assert places.ahead(route, 8.0, 0.5, 2.0) == pytest.approx(0.5)  # near the end: 0.5 m on already is
    # a route end closer than ``near`` still counts: the robot scans there
    assert places.ahead(route, 8.3, 0.5, 2.0) == pytest.approx(0.2)
    assert places.ahead(route, 6.0, 0.5, 0.6) == pytest.approx(0.6)  # ``far`` itself is a candidate


def test_the_place_behind_a_route_end_in_a_corridor_is_back_where_the_far_wall_is_in_range():
    places = _corridor_places()
    route = np.array([[1.0, 0.6], [6.0, 0.6]])
    np.testing.assert_allclose(places.behind(route, np.array([6.0, 0.6]), 0.5, 5.0), [2.4, 0.6], atol=1e-9)
    assert places.behind(route, np.array([6.0, 0.6]), 0.5, 2.0) is None  # x 4-5.5: nothing within 2 m
    assert places.behind(route, np.array([6.0, 0.6]), 0.5, 6.0) is not None
    # ``far`` itself is a candidate, nothing beyond it is
    np.testing.assert_allclose(places.behind(route, np.array([6.0, 0.6]), 0.5, 3.6), [2.4, 0.6], atol=1e-9)
    assert places.behind(route, np.array([6.0, 0.6]), 0.5, 3.5) is None
    # a route starting at x = 2: the place 0.4 m after its start
    short = np.array([[2.0, 0.6], [6.0, 0.6]])
    np.testing.assert_allclose(places.behind(short, np.array([6.0, 0.6]), 0.5, 5.0), [2.4, 0.6], atol=1e-9)
    # a wall between the robot and the route: not a place it can drive back to in a straight line
    walled = _corridor_places()
    walled.segments = np.vstack([walled.segments, [[5.8, 0.0, 5.8, 1.2]]])  # right behind the robot
    assert walled.behind(route, np.array([6.0, 0.6]), 0.5, 5.0) is None


def _fixer(**cfg):
    from parcover_env.expert.config import SonarFixConfig
    from parcover_env.expert.sonar_fix import SonarFixer

    cfg = {"relocate_distance": 0.5, **cfg}
    return SonarFixer(parcover_env.load_scenario("tree"), np.radians(np.arange(0, 360, 45.0)), 0.1,
                      SonarFixConfig(refused_rescans=2, rescan_distance=2.0, **cfg), env_scan=True)


def _after_scan(fixer, result):
    """Robot 0 asked for an env scan, which ended (no fresh fix) with ``result``; returns its state."""
    from parcover_env.expert.sonar_fix import SCAN_REQUEST, _State

    odom, ranges = np.array([1.0, 1.0, 0.0]), np.full(len(fixer.beams), 1.0)
    st = _State(np.zeros(3), np.eye(3) * 1e-3, driven_since_scan=0.0, last_odom=odom.copy())
    fixer.states["robot_0"] = st
    kw = {"fix_age": 100.0, "speed": 0.0, "ranges": ranges, "is_leader": True}
    assert fixer.step("robot_0", odom, check=True, **kw) == SCAN_REQUEST
    assert fixer.step("robot_0", odom, scanning=True, **kw) == (0.0, 0.0)
    assert fixer.step("robot_0", odom, scanning=False, result=result, **kw) is None
    return st, odom, kw


@pytest.mark.parametrize("result", [HELD, UNINFORMATIVE])
def test_a_held_or_uninformative_scan_is_not_repeated_in_place_but_after_the_chosen_drive(result):
    from parcover_env.expert.sonar_fix import SCAN_REQUEST

    fixer = _fixer()
    st, odom, kw = _after_scan(fixer, result)
    assert st.relocate and not st.missed and fixer.needs_place("robot_0")
    for _ in range(5):  # a rejected scan would be repeated at once (refused_rescans); this one is not
        assert fixer.step("robot_0", odom, **kw) is None
    fixer.scan_after("robot_0", 0.6)
    assert not fixer.needs_place("robot_0") and fixer.relocating("robot_0")
    moving = dict(kw, speed=0.25)  # 0.025 m per 0.1 s step
    steps = 0
    while fixer.step("robot_0", odom, **moving) is None:
        steps += 1
    assert steps == 23  # 24 x 0.025 m = 0.6 m driven: due; still rolling, so it brakes first
    assert fixer.step("robot_0", odom, **kw) == SCAN_REQUEST
    assert st.scan == "env"


def test_a_rejected_scan_is_still_repeated_at_once_and_relocation_off_treats_all_alike():
    from parcover_env.expert.sonar_fix import SCAN_REQUEST

    fixer = _fixer()
    st, odom, kw = _after_scan(fixer, REJECTED)
    assert st.missed and not st.relocate
    assert fixer.step("robot_0", odom, **kw) == SCAN_REQUEST  # the env searches a wider region now
    from parcover_env.expert.config import SonarFixConfig

    assert SonarFixConfig().relocate_distance == 0.5  # on by default (0 = off)
    off = _fixer(relocate_distance=0.0)
    st, odom, kw = _after_scan(off, HELD)
    assert st.missed and not st.relocate
    assert off.step("robot_0", odom, **kw) == SCAN_REQUEST


def test_a_fresh_fix_ends_the_relocation():
    fixer = _fixer()
    st, odom, kw = _after_scan(fixer, UNINFORMATIVE)
    fixer.scan_after("robot_0", 0.6)
    assert fixer.step("robot_0", odom, **dict(kw, fix_age=0.0)) is None
    assert not st.relocate and st.move is None


RELOCATE = {"observation": {"scan": {"enabled": True, "confirm_widened": True}},
            "expert": {"sonar_fix": {"relocate_distance": 0.5}}}
"""The measured opt-in variant: held fixes (``confirm_widened``) and the expert's relocation."""


def _expert_at(env, pose):
    """The registered expert after reset, robot 0's observation put at ``pose`` (leader, stale)."""
    from parcover_env.expert import expert_for

    expert = expert_for(env)
    obs, _ = env.reset(seed=3)
    expert.reset(obs)
    o = obs["robot_0"].copy()
    for name, value in {"x": pose[0], "y": pose[1], "cos_theta": math.cos(pose[2]),
                        "sin_theta": math.sin(pose[2])}.items():
        o[env.layout.slices[name]] = value
    return expert, o


def test_the_expert_at_its_route_end_drives_back_to_an_informative_place_and_scans_there():
    env = parcover_env.parallel_env("generated:3", overrides=RELOCATE)
    assert env.scenario.observation.scan.confirm_widened
    route = env.mission.routes[0]
    end = route[-1]
    pose = np.array([end[0], end[1], 0.0])
    expert, o = _expert_at(env, pose)
    _after_scan(expert.fixer, UNINFORMATIVE)
    expert.fixer.states["robot_0"].last_odom = pose.copy()
    expert._relocate("robot_0", 0, pose, True, np.full(16, 1.0))
    place = expert.places.behind(route, pose[:2], 0.5, 2.0)
    assert place is not None and 0.5 - 1e-9 <= np.hypot(*(place - end)) <= 2.0
    np.testing.assert_array_equal(expert.detours["robot_0"], place)
    assert expert.fixer.states["robot_0"].move == math.inf  # not before it gets there
    goal = expert._goal(o, "robot_0", None)  # it steers to the place (robot frame)
    np.testing.assert_allclose(goal, place - pose[:2], atol=1e-6)  # float32 observation
    there = np.array([place[0], place[1], 0.0])
    expert._relocate("robot_0", 0, there, False, np.full(16, 1.0))  # arrived: the scan is due now
    assert expert.fixer.states["robot_0"].move == 0.0
    expert.fixer.states["robot_0"].scan = "env"
    expert._relocate("robot_0", 0, there, False, np.full(16, 1.0))  # scanning: the detour is done
    assert "robot_0" not in expert.detours


def test_the_expert_away_from_its_route_end_scans_at_the_next_informative_place_ahead():
    env = parcover_env.parallel_env("generated:3", overrides=RELOCATE)
    route = env.mission.routes[0]
    pose = np.array([route[0][0], route[0][1], 0.0])
    expert, _ = _expert_at(env, pose)
    _after_scan(expert.fixer, HELD)
    expert._relocate("robot_0", 0, pose, False, np.full(16, 1.0))
    ahead = expert.places.ahead(route, float(expert.track.progress[0]), 0.5, 2.0)
    expected = 2.0 if ahead is None else ahead
    assert 0.5 - 1e-9 <= expected <= 2.0
    assert expert.fixer.states["robot_0"].move == pytest.approx(expected)
    assert "robot_0" not in expert.detours


def test_outcome_values_keep_a_miss_negative():
    assert (ACCEPTED, HELD, UNINFORMATIVE, REJECTED) == (1.0, 0.5, -0.5, -1.0)


def _scan_again(fixer, result):
    """Robot 0, already set up by :func:`_after_scan`, asks for one more env scan (due now) ending with ``result``."""
    from parcover_env.expert.sonar_fix import SCAN_REQUEST

    odom = np.array([1.0, 1.0, 0.0])
    kw = {"fix_age": 100.0, "speed": 0.0, "ranges": np.full(len(fixer.beams), 1.0), "is_leader": True}
    fixer.scan_after("robot_0", 0.0)
    assert fixer.step("robot_0", odom, **kw) == SCAN_REQUEST
    assert fixer.step("robot_0", odom, scanning=True, **kw) == (0.0, 0.0)
    assert fixer.step("robot_0", odom, scanning=False, result=result, **kw) is None


def test_a_second_uninformative_scan_in_a_row_spaces_the_scans_until_a_fix():
    fixer = _fixer()
    st, odom, kw = _after_scan(fixer, UNINFORMATIVE)
    assert not fixer.spaced("robot_0") and st.uninformative == 1
    _scan_again(fixer, UNINFORMATIVE)  # at the place the expert chose: uninformative again
    assert fixer.spaced("robot_0") and st.uninformative == 2 and fixer.relocating("robot_0")
    _scan_again(fixer, HELD)  # not a fix: still spaced
    assert fixer.spaced("robot_0") and fixer.held("robot_0") and st.uninformative == 0
    assert fixer.step("robot_0", odom, **dict(kw, fix_age=0.0)) is None  # a fix ends it
    assert not fixer.spaced("robot_0") and not fixer.held("robot_0") and not fixer.relocating("robot_0")
    # uninformative, held, uninformative: never two in a row
    fixer = _fixer()
    _after_scan(fixer, UNINFORMATIVE)
    _scan_again(fixer, HELD)
    assert fixer.held("robot_0")
    _scan_again(fixer, UNINFORMATIVE)
    assert not fixer.spaced("robot_0") and not fixer.held("robot_0")
    # relocation off: nothing of this
    off = _fixer(relocate_distance=0.0)
    st, _, _ = _after_scan(off, UNINFORMATIVE)
    assert not off.spaced("robot_0") and st.missed


def _relocating_expert(result, count=1, then=()):
    """The registered expert's robot 0 at its route's start after ``count`` env scans ending in
    ``result``, then scans ending in each of ``then``; the known map's place prediction stubbed: 0.7 m
    ahead, nothing behind."""
    from types import SimpleNamespace

    env = parcover_env.parallel_env("generated:3", overrides=RELOCATE)
    route = env.mission.routes[0]
    pose = np.array([route[0][0], route[0][1], 0.0])
    expert, _ = _expert_at(env, pose)
    _after_scan(expert.fixer, result)
    for later in [result] * (count - 1) + list(then):
        _scan_again(expert.fixer, later)
    expert.fixer.states["robot_0"].move = None  # the expert has not chosen the place of the next scan yet
    expert.places = SimpleNamespace(ahead=lambda *args: 0.7, behind=lambda *args: None, behind_at=lambda *args: None)
    return expert, pose


def test_after_two_uninformative_scans_the_expert_scans_rescan_distance_on_not_at_the_predicted_place():
    ranges = np.full(16, 1.0)
    expert, pose = _relocating_expert(UNINFORMATIVE, count=1)
    expert._relocate("robot_0", 0, pose, False, ranges)
    assert expert.fixer.states["robot_0"].move == pytest.approx(0.7)  # the predicted place
    expert, pose = _relocating_expert(UNINFORMATIVE, count=2)
    expert._relocate("robot_0", 0, pose, False, ranges)
    assert expert.fixer.states["robot_0"].move == pytest.approx(2.0)  # rescan_distance
    assert expert.cfg.sonar_fix.rescan_distance == 2.0
    # still spaced, but the last scan was held (informative): to the predicted place, to confirm it soon
    expert, pose = _relocating_expert(UNINFORMATIVE, count=2, then=[HELD])
    assert expert.fixer.spaced("robot_0") and expert.fixer.held("robot_0")
    expert._relocate("robot_0", 0, pose, False, ranges)
    assert expert.fixer.states["robot_0"].move == pytest.approx(0.7)


def test_a_stuck_robot_with_a_held_fix_drives_into_the_freest_sonar_direction_then_scans():
    expert, pose = _relocating_expert(HELD)
    c, dt = expert.cfg.sonar_fix, expert.dt
    assert (c.stuck_time, c.stuck_distance, c.relocate_distance, dt) == (5.0, 0.1, 0.5, 0.1)
    assert expert.stop == pytest.approx(0.17)  # robot radius 0.12 + stop_margin 0.05
    ranges = np.full(16, 0.3)
    ranges[3:6] = 2.5  # free at 90 degrees to the left (beams every 22.5 degrees), its front sector too
    ranges[9:12] = 2.5  # as free: the first counts
    ranges[14] = 2.5  # the longest reading, but its neighbours (within front_sector_deg 25) are 0.3 m
    expert._relocate("robot_0", 0, pose, False, ranges)
    assert expert.fixer.states["robot_0"].move == pytest.approx(0.7)  # drives on to the predicted place
    # it does not get anywhere: braked, and jiggling 0.09 m back and forth does not count as moving
    for k in range(49):
        jiggle = pose + np.array([0.09 * (k % 2), 0.0, 0.0])
        expert._relocate("robot_0", 0, jiggle, False, ranges)
        assert "robot_0" not in expert.detours, k
    expert._relocate("robot_0", 0, pose, False, ranges)  # 50 steps on = 5 s without moving 0.1 m
    np.testing.assert_allclose(expert.detours["robot_0"], pose[:2] + [0.0, 0.5], atol=1e-9)
    assert "robot_0" in expert.escaping and expert.fixer.states["robot_0"].move == math.inf
    # on its way: no scan; 0.05 m from the place: scan now
    expert._relocate("robot_0", 0, pose + [0.0, 0.3, 0.0], False, ranges)
    assert expert.fixer.states["robot_0"].move == math.inf
    expert._relocate("robot_0", 0, pose + [0.0, 0.46, 0.0], False, ranges)
    assert expert.fixer.states["robot_0"].move == 0.0
    # the scan starts: the escape is over
    expert.fixer.states["robot_0"].scan = "env"
    expert._relocate("robot_0", 0, pose, False, ranges)
    assert "robot_0" not in expert.detours and not expert.escaping and "robot_0" not in expert.still


def test_an_escape_is_shorter_before_a_near_echo_and_ends_where_the_robot_is_stuck_again():
    expert, pose = _relocating_expert(HELD)
    ranges = np.full(16, 0.2)
    ranges[7:10] = [0.6, 0.45, 0.5]  # behind it the shortest of its sector is 0.45 m: it stops stop_margin
    # short of that (0.45 - 0.17 = 0.28 m)
    for _ in range(51):
        expert._relocate("robot_0", 0, pose, False, ranges)
    np.testing.assert_allclose(expert.detours["robot_0"], pose[:2] + [-0.28, 0.0], atol=1e-9)
    for _ in range(49):  # blocked on the way
        expert._relocate("robot_0", 0, pose + [-0.05, 0.0, 0.0], False, ranges)
        assert expert.fixer.states["robot_0"].move == math.inf
    expert._relocate("robot_0", 0, pose + [-0.05, 0.0, 0.0], False, ranges)
    assert expert.fixer.states["robot_0"].move == 0.0  # scans from as far as it got


def test_no_escape_when_boxed_in_or_standing_at_its_route_end_after_an_uninformative_scan():
    expert, pose = _relocating_expert(HELD)
    boxed = np.full(16, 0.25)  # 0.25 - 0.17 = 0.08 m < stuck_distance: nowhere to go
    for _ in range(120):
        expert._relocate("robot_0", 0, pose, False, boxed)
    assert "robot_0" not in expert.detours and expert.fixer.states["robot_0"].move == pytest.approx(0.7)
    ranges = np.full(16, 2.5)
    expert, pose = _relocating_expert(UNINFORMATIVE)  # at its route's end it stands still on purpose
    for _ in range(120):
        expert._relocate("robot_0", 0, pose, True, ranges)
    assert "robot_0" not in expert.detours and expert.fixer.states["robot_0"].move == math.inf
    expert, pose = _relocating_expert(UNINFORMATIVE)  # on its way it does not: it escapes (beam 0, ahead)
    for _ in range(51):
        expert._relocate("robot_0", 0, pose, False, ranges)
    np.testing.assert_allclose(expert.detours["robot_0"], pose[:2] + [0.5, 0.0], atol=1e-9)
    assert expert.fixer.states["robot_0"].move == math.inf


def test_the_registered_expert_holds_widened_fixes_except_for_the_sonar_navigator():
    from parcover_env.policies.registry import policy_overrides

    held = {"observation": {"scan": {"enabled": True, "confirm_widened": True}}}
    assert policy_overrides("expert", "generated:3") == held
    assert policy_overrides("expert", "t_room") == held
    assert policy_overrides("expert", "hallway") == {"observation": {"scan": {"enabled": True}}}  # navigator
    assert policy_overrides("expert") == {"observation": {"scan": {"enabled": True}}}  # no scenario named
    assert policy_overrides("waypoint", "generated:3") == {"observation": {"scan": {"enabled": True}}}
    first = policy_overrides("expert", "generated:3")
    first["observation"]["scan"]["confirm_widened"] = False  # a caller's change does not stick
    assert policy_overrides("expert", "generated:3") == held


def test_behind_at_says_how_far_back_the_place_lies():
    places = _corridor_places()
    route = np.array([[1.0, 0.6], [6.0, 0.6]])
    place, back = places.behind_at(route, np.array([6.0, 0.6]), 0.5, 5.0)
    np.testing.assert_allclose(place, [2.4, 0.6], atol=1e-9)
    assert back == pytest.approx(3.6)
    assert places.behind_at(route, np.array([6.0, 0.6]), 0.5, 2.0) is None
