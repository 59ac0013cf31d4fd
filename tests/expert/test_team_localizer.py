"""Team localization: which readings a teammate may explain (pure geometry, hand-built scans)."""

from __future__ import annotations

import numpy as np

import parcover_env
from parcover_env.expert.team_localizer import teammate_mask


def test_only_short_readings_ending_near_a_teammate_are_masked():
    pose = np.array([0.0, 0.0, np.pi / 2])  # facing +y
    angles = np.radians([0.0, 90.0, 180.0, 270.0])  # robot frame: ahead (+y), left (-x), behind, right (+x)
    expected = np.full(4, 2.0)  # the known map: a wall 2 m away all round
    ranges = np.array([0.5, 2.0, 0.5, 0.5])  # three short readings, one wall reading
    others = np.array([[0.0, 0.8]])  # a teammate believed 0.8 m ahead
    # reach 0.4 m: the reading ahead ends at (0, 0.5), 0.3 m from the teammate -> masked; the one
    # behind ends at (0, -0.5), 1.3 m away -> kept; the one to the right at (0.5, 0) -> 0.94 m, kept
    m = teammate_mask(pose, angles, ranges, expected, others, np.array([0.4]))
    assert m.tolist() == [True, False, False, False]
    # a reading as long as the map's is never blamed on a teammate, however uncertain it is
    m = teammate_mask(pose, angles, ranges, expected, others, np.array([5.0]))
    assert m.tolist() == [True, False, True, True]
    # a smaller reach leaves the reading ahead in the comparison
    m = teammate_mask(pose, angles, ranges, expected, others, np.array([0.25]))
    assert not m.any()


def _scan_pin(size, pose):
    from types import SimpleNamespace

    from parcover_env.config.schema import MapConfig
    from parcover_env.expert.config import expert_config
    from parcover_env.expert.team_localizer import TeamLocalizer, shift_sensitivity
    from parcover_env.localization.sonar.config import sonar_localizer_config
    from parcover_env.sensors.sonar import simulate_beams

    sc = parcover_env.load_scenario("generated:120")
    team = TeamLocalizer(SimpleNamespace(map=MapConfig(size=size), robot=sc.robot), expert_config(sc).navigator,
                         sonar_localizer_config(sc))
    pose = np.asarray(pose, dtype=float)
    ranges = simulate_beams(sc.robot.sonar, pose[None, :2], (pose[2] + team.scan_angles)[None, :], team.map.segments,
                            np.zeros((0, 2)), sc.robot.radius, np.array([-1]))[0]
    errors = team.shifted_errors(ranges, pose, np.zeros((0, 2)), 0.2)
    return errors, shift_sensitivity(errors)


def test_a_scan_in_a_long_corridor_does_not_pin_the_pose_along_it():
    errors, pin = _scan_pin((12.0, 1.2), [6.0, 0.6, 0.0])
    assert errors[0] == 0.0  # the scan is the synthetic scan at the pose itself
    along, across = errors[[1, 5]], errors[[3, 7]]  # shifts along +-x (the corridor) and +-y
    assert np.all(along < 0.005) and np.all(across > 0.02)
    assert pin < 0.01


def test_a_scan_in_a_small_room_pins_the_pose_in_every_direction():
    errors, pin = _scan_pin((3.0, 2.5), [1.0, 1.0, 0.3])
    assert errors[0] == 0.0
    assert pin >= 0.01
