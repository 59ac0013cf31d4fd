"""Seed A Fig. 11: the office's Kinect sees the start, the TP and both KPOIs; Kinect-only scenarios
with points no Kinect sees are rejected when they load."""

from __future__ import annotations

import pytest

from parcover_env.errors import ConfigError
from parcover_env.geometry.camera import CameraModel
from parcover_env.scenarios import load_scenario
from parcover_env.scenarios.validation import kinect_blind_spots
from parcover_env.world.map_model import map_model


def test_office_kinect_sees_start_tp_and_both_kpois():
    s = load_scenario("office")
    assert s.localization == "kinect" and len(s.kinects) == 1
    assert kinect_blind_spots(s) == []
    free = map_model(s.map, False).free
    cam = CameraModel.from_config(s.kinects[0])
    assert cam.footprint().intersection(free).area / free.area == pytest.approx(0.867, abs=0.005)
    assert cam.footprint(s.robot.height).intersection(free).area / free.area == pytest.approx(0.723, abs=0.005)


def test_footprint_at_marker_height_shrinks_towards_the_camera():
    s = load_scenario("office")
    cam = CameraModel.from_config(s.kinects[0])
    floor, top = cam.footprint(), cam.footprint(0.3)
    # looking straight down from 3.9 m: linear size scales with the distance to the plane
    assert top.area / floor.area == pytest.approx((3.6 / 3.9) ** 2, rel=1e-6)
    assert floor.contains(top)


def test_kinect_only_scenario_with_an_unseen_kpoi_is_rejected():
    with pytest.raises(ConfigError, match=r"kpois\[0\].*seen by no Kinect"):
        load_scenario("office", {"kpois": [[0.3, 4.35], [2.75, 0.55]]})
    # with the sonar fallback the same layout is accepted
    s = load_scenario("office", {"kpois": [[0.3, 4.35], [2.75, 0.55]], "localization": "both"})
    assert [k for k, _ in kinect_blind_spots(s)] == ["kpois[0]"]
