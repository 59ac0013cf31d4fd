"""The waypoint policy uses the env's sonar localization service: it scans when its uncertainty
ellipse exceeds the localizer's tolerance, retries a rejected scan, then waits for its sigma to grow."""

from __future__ import annotations

import numpy as np
import pytest

import parcover_env
from parcover_env.policies.registry import policy_overrides
from parcover_env.policies.simple import WaypointPolicy, default_scan_sigma


@pytest.fixture(scope="module")
def layout():
    return parcover_env.parallel_env("t_room", overrides=policy_overrides("waypoint")).layout


def _obs(layout, sigma, scanning=0.0, result=0.0):
    o = np.zeros(layout.size, np.float32)
    for name, value in (("goal_dx", 1.0), ("sigma_major", sigma), ("scanning", scanning), ("scan_result", result)):
        o[layout.slices[name]] = value
    return {"robot_0": o}


def test_threshold_is_the_localizers_tolerance_over_its_sigmas():
    assert default_scan_sigma() == pytest.approx(0.3 / 2)
    assert policy_overrides("waypoint") == {"observation": {"scan": {"enabled": True}}}


def test_scans_above_the_threshold_only(layout):
    pol = WaypointPolicy(layout)
    drive = pol.act(_obs(layout, 0.149))["robot_0"]
    assert drive.shape == (3,) and drive[0] > 0.5 and drive[2] == -1.0
    np.testing.assert_array_equal(pol.act(_obs(layout, 0.151))["robot_0"], [0.0, 0.0, 1.0])
    assert pol.act(_obs(layout, 0.151, scanning=1.0))["robot_0"][2] == -1.0  # no new request mid-scan
    assert pol.stats() == {"scans": 1}


@pytest.mark.parametrize("miss", [-1.0, -0.5])  # rejected, uninformative: both a miss to this policy
def test_rejected_scan_is_retried_twice_then_waits_for_more_drift(layout, miss):
    pol = WaypointPolicy(layout)
    scans = []
    sigma = 0.2
    assert pol.act(_obs(layout, sigma))["robot_0"][2] == 1.0
    for _ in range(3):  # three rejections in a row: two immediate retries, then none
        pol.act(_obs(layout, sigma, scanning=1.0))
        scans.append(pol.act(_obs(layout, sigma, result=miss))["robot_0"][2])
    assert scans == [1.0, 1.0, -1.0]
    assert pol.act(_obs(layout, 1.5 * sigma - 0.01, result=-1.0))["robot_0"][2] == -1.0
    assert pol.act(_obs(layout, 1.5 * sigma + 0.01, result=-1.0))["robot_0"][2] == 1.0
    pol.act(_obs(layout, 0.31, scanning=1.0))
    assert pol.act(_obs(layout, 0.05, result=1.0))["robot_0"][2] == -1.0  # accepted: sigma small again
    assert pol.stats() == {"scans": 4}  # the first, two retries, one after more drift


def test_without_the_service_it_drives_with_two_components():
    layout = parcover_env.parallel_env("t_room").layout
    act = WaypointPolicy(layout).act(_obs_plain(layout))["robot_0"]
    assert act.shape == (2,) and act[0] > 0.5


def _obs_plain(layout):
    o = np.zeros(layout.size, np.float32)
    o[layout.slices["goal_dx"]] = 1.0
    o[layout.slices["sigma_major"]] = 5.0
    return {"robot_0": o}
