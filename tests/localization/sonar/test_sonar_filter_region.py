"""Seed B Fig. 11 filter on hand-built scans; covariance uncertainty regions; localizer config."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import ConfigError, MapConfig, SonarConfig
from parcover_env.localization.sonar import compute_sectors, map_features
from parcover_env.localization.sonar.config import SonarLocalizerConfig, sonar_localizer_config
from parcover_env.localization.sonar.filter import filter_scan
from parcover_env.localization.sonar.localizer import Ellipse, localize
from parcover_env.scenarios import load_scenario
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.map_model import MapModel

ANGLES = np.radians(np.arange(72) * 5.0)


def _corner_scan() -> np.ndarray:
    """From the origin: the wall x = 1 (ahead) meets the wall y = 1.5 (left) in a concave corner."""
    c, s = np.cos(ANGLES), np.sin(ANGLES)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 1e-9, 1.0 / c, np.inf)
        ty = np.where(s > 1e-9, 1.5 / s, np.inf)
    return np.minimum(np.minimum(tx, ty), 2.54)


def test_fig11_moves_too_long_readings_beside_the_nearest_wall_onto_it():
    true = _corner_scan()
    bad = true.copy()
    bad[[2, 3, 69]] = [1.5, 2.54, 1.4]  # multipath / lost echoes on the wall x = 1, farther than it
    out = filter_scan(bad, ANGLES, 2.54, repeats=1)
    np.testing.assert_allclose(out[[1, 2, 3, 69, 70]], true[[1, 2, 3, 69, 70]], atol=1e-9)
    # the corner (a local maximum at atan2(1.5, 1) = 56 deg) and the other wall are left alone
    corner = int(round(math.degrees(math.atan2(1.5, 1.0)) / 5))
    np.testing.assert_array_equal(out[corner - 1:corner + 6], bad[corner - 1:corner + 6])


def test_fig11_stops_where_the_line_runs_behind_a_nearer_reading():
    true = _corner_scan()
    out = filter_scan(true, ANGLES, 2.54, repeats=3)
    # a clean scan is unchanged: past the corner, the next wall is nearer than L's extension
    np.testing.assert_allclose(out, true, atol=1e-9)


def test_fig11_skips_a_minimum_whose_neighbours_are_not_a_line():
    r = np.full(72, 2.0)
    r[10], r[9], r[11] = 0.5, 1.5, 0.9  # a spike, not a wall
    out = filter_scan(r, ANGLES, 2.54, repeats=1)
    np.testing.assert_array_equal(out, r)


def test_ellipse_from_covariance_axes_and_orientation():
    a = 0.5
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    cov = rot @ np.diag([0.09, 0.01]) @ rot.T
    e = Ellipse.from_covariance((1.0, 2.0), cov, 2.0)
    assert e.axes == pytest.approx((0.6, 0.2)) and e.angle == pytest.approx(a)
    assert e.center == (1.0, 2.0)
    with pytest.raises(ValueError, match="semi-definite"):
        Ellipse.from_covariance((0, 0), [[1.0, 0.0], [0.0, -1.0]])
    with pytest.raises(ValueError, match="symmetric"):
        Ellipse.from_covariance((0, 0), [[1.0, 0.5], [0.0, 1.0]])


def test_localize_accepts_a_position_covariance():
    m = MapModel.from_config(MapConfig(size=(4.0, 4.0), boundary=(
        (1.2, 0.0), (2.8, 0.0), (2.8, 2.4), (4.0, 2.4), (4.0, 4.0), (0.0, 4.0), (0.0, 2.4), (1.2, 2.4))))
    feats = map_features(m)
    sectors = compute_sectors(m, 2.54, 2, feats)
    sonar = SonarConfig(model="ray")
    ring = SonarRing(sonar)
    pose = (3.2, 3.0, 1.0)
    scan = ring.scan(pose, m.segments, None, 0.165, None)
    cov = np.array([[0.02, 0.01], [0.01, 0.03]])
    p = SonarLocalizerConfig()
    a = localize(scan, ring.scan_angles, m, sectors, ((3.3, 2.9), cov), p, sonar=sonar, features=feats)
    b = localize(scan, ring.scan_angles, m, sectors, Ellipse.from_covariance((3.3, 2.9), cov, p.covariance_sigmas),
                 p, sonar=sonar, features=feats)
    assert a.success and np.linalg.norm(a.pose[:2] - pose[:2]) < 0.03
    np.testing.assert_array_equal(a.pose, b.pose)
    # a thin region far from the robot finds nothing there
    far = localize(scan, ring.scan_angles, m, sectors, ((0.5, 3.5), np.diag([1e-4, 1e-4])), p, sonar=sonar,
                   features=feats)
    assert far.pose is None or np.linalg.norm(far.pose[:2] - pose[:2]) > 1.0


def test_localizer_configs_are_read_from_the_scenario_yaml():
    s = load_scenario("t_room", {"sonar_localizer": {"filter": False, "filter_repeats": 5},
                                 "kinect_tracking": {"gate": 0.8}})
    loc = sonar_localizer_config(s)  # the localizer owns its section's schema
    assert loc.filter is False and loc.filter_repeats == 5 and loc.window == SonarLocalizerConfig().window
    assert s.kinect_tracking.gate == 0.8
    assert load_scenario("t_room").kinect_tracking.gate == 1.0
    with pytest.raises(ConfigError, match="sonar_localizer.filter_repeats"):
        sonar_localizer_config(load_scenario("t_room", {"sonar_localizer": {"filter_repeats": 0}}))
    with pytest.raises(ConfigError, match="kinect_tracking.fuse_radius"):
        load_scenario("t_room", {"kinect_tracking": {"gate": 0.1, "fuse_radius": 0.2}})
