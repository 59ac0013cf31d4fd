"""Sonar localizer (Fig. 6) and the uncertainty ellipse."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from parcover_env.config import MapConfig, SonarConfig
from parcover_env.errors import ConfigError
from parcover_env.localization.sonar.config import SonarLocalizerConfig
from parcover_env.localization.sonar.features import map_features
from parcover_env.localization.sonar.localizer import Ellipse, localize
from parcover_env.localization.sonar.sectors import compute_sectors
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.map_model import MapModel

T_ROOM = MapConfig(size=(4.0, 4.0), boundary=((1.2, 0.0), (2.8, 0.0), (2.8, 2.4), (4.0, 2.4), (4.0, 4.0),
                                              (0.0, 4.0), (0.0, 2.4), (1.2, 2.4)))


def test_ellipse_grows_linearly_and_measures_distance():
    e = Ellipse((1.0, 2.0), (0.2, 0.1), 0.0)
    g = e.grow(2.0, math.pi, rate_distance=0.1, rate_rotation=0.05)
    assert g.axes == pytest.approx((0.2 + 0.2 + 0.05 * math.pi, 0.1 + 0.2 + 0.05 * math.pi))
    d = e.distance([[1.0, 2.0], [1.5, 2.0], [1.0, 2.4]])
    assert d == pytest.approx([0.0, 0.3, 0.3], abs=1e-3)
    with pytest.raises(ValueError, match="axes"):
        Ellipse((0, 0), (-1, 1))


@pytest.mark.parametrize("model", ["ray", "specular"])
def test_localize_t_room(model):
    m = MapModel.from_config(T_ROOM)
    feats = map_features(m)
    sectors = compute_sectors(m, 2.54, 2, feats)
    sonar = SonarConfig(model=model)
    ring = SonarRing(sonar)
    rng = np.random.default_rng(5)
    ok = 0
    poses = [(2.0, 1.0, 0.4), (1.9, 2.0, 2.0), (0.8, 3.2, -2.5), (3.2, 3.0, 1.0), (2.1, 3.4, -0.7)]
    for pose in poses:
        scan = ring.scan(pose, m.segments, None, 0.165, rng)
        ell = Ellipse((pose[0] + 0.15, pose[1] - 0.1), (0.3, 0.3))
        res = localize(scan, ring.scan_angles, m, sectors, ell, sonar=sonar, features=feats)
        if res.success:
            assert res.candidates_tried >= 1 and res.feature >= 0
            tol = math.radians(3 if model == "ray" else 6)
            ok += bool(np.linalg.norm(res.pose[:2] - pose[:2]) < 0.06
                       and abs(math.remainder(res.pose[2] - pose[2], 2 * math.pi)) < tol)
    assert ok >= 4  # specular: (1.9, 2.0) is ambiguous in the stem (see wrong-but-confident in the benchmark)


def test_localize_rejects_a_wrong_ellipse_and_bad_input():
    m = MapModel.from_config(T_ROOM)
    feats = map_features(m)
    sectors = compute_sectors(m, 2.54, 2, feats)
    ring = SonarRing(SonarConfig(model="ray"))
    scan = ring.scan((2.0, 1.0, 0.4), m.segments, None, 0.165, None)
    # with the robot's heading estimate (odometry), as the env's users pass it: the scan comparison
    # leaves out the worst 10 % of readings, so a look-alike pose in the top bar is ruled out by heading
    res = localize(scan, ring.scan_angles, m, sectors, Ellipse((0.6, 3.4), (0.2, 0.2)), features=feats, heading=0.4)
    assert not res.success
    strict = SonarLocalizerConfig(error_trim=0.0)
    assert not localize(scan, ring.scan_angles, m, sectors, Ellipse((0.6, 3.4), (0.2, 0.2)), strict,
                        features=feats).success
    with pytest.raises(ValueError, match="scan_ranges"):
        localize(scan[:10], ring.scan_angles, m, sectors, Ellipse((2, 1), (0.2, 0.2)))
    with pytest.raises(ValueError, match="Ellipse"):
        localize(scan, ring.scan_angles, m, sectors, (2, 1))


SQUARE = MapConfig(size=(2.4, 2.4))


def test_a_thin_covariance_ellipse_picks_the_look_alike_along_its_major_axis():
    # a square room looks the same from (0.8, 0.8, 0) and from that pose turned by 90, 180, 270 deg
    # about the centre, e.g. (0.8, 1.6, -90 deg); only the uncertainty region tells them apart. The
    # region is given as mean + 2x2 covariance (2 sigma ellipse): thin along y it holds the true pose,
    # the same ellipse thin along x holds no pose that explains the scan.
    m = MapModel.from_config(SQUARE)
    feats = map_features(m)
    sectors = compute_sectors(m, 2.54, 2, feats)
    ring = SonarRing(SonarConfig(model="ray"))
    truth = np.array([0.8, 0.8, 0.0])
    scan = ring.scan(truth, m.segments, None, 0.165, None)
    twin = ring.scan((0.8, 1.6, -math.pi / 2), m.segments, None, 0.165, None)
    assert np.abs(scan - twin).max() < 1e-6  # the look-alike is exact
    p = SonarLocalizerConfig(ellipse_distance=0.05, covariance_sigmas=2.0)
    mean = np.array([0.8, 1.1])
    along_y = np.diag([0.015**2, 0.175**2])  # 2 sigma: 0.03 m across, 0.35 m along y
    res = localize(scan, ring.scan_angles, m, sectors, (mean, along_y), p, features=feats)
    assert res.success
    assert np.hypot(*(res.pose[:2] - truth[:2])) < 0.03 and abs(math.remainder(res.pose[2], 2 * math.pi)) < 0.05
    along_x = np.diag([0.175**2, 0.015**2])
    res = localize(scan, ring.scan_angles, m, sectors, (mean, along_x), p, features=feats)
    assert res.pose is None or not res.success
    # the ellipse of the covariance: semi-axes 2 sigma along the eigenvectors
    e = Ellipse.from_covariance(mean, along_y, 2.0)
    assert e.axes == pytest.approx((0.35, 0.03)) and abs(math.remainder(e.angle - math.pi / 2, math.pi)) < 1e-9


def test_heading_tolerance_argument_replaces_the_configured_one():
    m = MapModel.from_config(T_ROOM)
    feats = map_features(m)
    sectors = compute_sectors(m, 2.54, 2, feats)
    ring = SonarRing(SonarConfig(model="ray"))
    pose = (2.0, 1.0, 0.4)
    scan = ring.scan(pose, m.segments, None, 0.165, None)
    ell = Ellipse((2.1, 0.95), (0.3, 0.3))
    p = SonarLocalizerConfig(grid_fallback=False)
    # odometry heading 20 deg off: the default 30 deg tolerance keeps the true pose, 10 deg drops it
    head = 0.4 + math.radians(20)
    assert localize(scan, ring.scan_angles, m, sectors, ell, p, features=feats, heading=head).success
    narrow = localize(scan, ring.scan_angles, m, sectors, ell, p, features=feats, heading=head,
                      heading_tol=math.radians(10))
    assert narrow.pose is None or abs(narrow.pose[2] - head) <= math.radians(10) + 0.1
    assert not narrow.success or np.hypot(*(narrow.pose[:2] - pose[:2])) > 0.05
    with pytest.raises(ValueError, match="heading_tol"):
        localize(scan, ring.scan_angles, m, sectors, ell, p, features=feats, heading=head, heading_tol=0.0)


def test_paper_method_switches_off_the_three_extensions_only():
    cfg = SonarLocalizerConfig(filter_repeats=5, error_trim=0.2)
    paper = cfg.paper_method()
    assert (cfg.polish, cfg.arc_fallback, cfg.grid_fallback) == (True, True, True)  # the defaults
    assert (paper.polish, paper.arc_fallback, paper.grid_fallback) == (False, False, False)
    assert dataclasses.replace(paper, polish=True, arc_fallback=True, grid_fallback=True) == cfg
    with pytest.raises(ConfigError, match="grid_step"):
        SonarLocalizerConfig(grid_step=0.0)


def _t_room():
    m = MapModel.from_config(T_ROOM)
    feats = map_features(m)
    return m, feats, compute_sectors(m, 2.54, 2, feats)


def test_arc_fallback_finds_the_pose_when_no_corner_wall_shows_its_foot():
    # close under the top wall of the bar, facing +x: no (corner, two walls) pair lands near the
    # ellipse, so the paper's method has no candidate; the arc of the corner's measured range does
    m, feats, sectors = _t_room()
    ring = SonarRing(SonarConfig(model="ray"))
    pose = np.array([1.8, 3.7, 0.0])
    scan = ring.scan(pose, m.segments, None, 0.165, None)
    ell = Ellipse((1.9, 3.65), (0.25, 0.25))
    paper = SonarLocalizerConfig().paper_method()
    alone = localize(scan, ring.scan_angles, m, sectors, ell, paper, features=feats, heading=0.0)
    assert alone.pose is None and alone.candidates_tried == 0 and not alone.success
    arc = localize(scan, ring.scan_angles, m, sectors, ell, dataclasses.replace(paper, arc_fallback=True),
                   features=feats, heading=0.0)
    assert arc.success and arc.candidates_tried > 10
    assert np.hypot(*(arc.pose[:2] - pose[:2])) < 0.03 and abs(arc.pose[2]) < math.radians(2)


def test_grid_fallback_scan_matches_where_no_feature_is_in_range():
    # the middle of an 8 m corridor: its four corners are beyond the 2.54 m range, no feature to
    # pair; the grid fallback finds a pose that explains the scan (across the corridor exactly; along
    # it the scan cannot tell, so within the ellipse) with the heading estimate's help
    m = MapModel.from_config(MapConfig(size=(8.0, 1.2)))
    feats = map_features(m)
    sectors = compute_sectors(m, 2.54, 2, feats)
    ring = SonarRing(SonarConfig(model="ray"))
    pose = np.array([4.0, 0.5, 0.3])
    scan = ring.scan(pose, m.segments, None, 0.165, None)
    ell = Ellipse((4.1, 0.55), (0.2, 0.2))
    paper = SonarLocalizerConfig().paper_method()
    assert localize(scan, ring.scan_angles, m, sectors, ell, paper, features=feats, heading=0.3).pose is None
    grid = dataclasses.replace(paper, grid_fallback=True)
    res = localize(scan, ring.scan_angles, m, sectors, ell, grid, features=feats, heading=0.3)
    assert res.success and abs(res.pose[1] - 0.5) < 0.03 and abs(res.pose[2] - 0.3) < 0.02
    assert ell.distance(res.pose[None, :2])[0] == 0.0
    # without a heading estimate the fallback does not run
    assert localize(scan, ring.scan_angles, m, sectors, ell, grid, features=feats).pose is None


def test_polish_cuts_the_error_of_the_feature_pose():
    # a noisy scan (1 cm quantized walls): the pose from the walls' feet is off by 1.4 cm; the
    # polish's local minimization of the scan error brings it within 0.5 cm
    m, feats, sectors = _t_room()
    ring = SonarRing(SonarConfig(model="ray"))
    pose = np.array([2.0, 1.0, 0.4])
    scan = ring.scan(pose, m.segments, None, 0.165, np.random.default_rng(1))
    ell = Ellipse((2.1, 0.9), (0.3, 0.3))
    paper = SonarLocalizerConfig().paper_method()
    a = localize(scan, ring.scan_angles, m, sectors, ell, paper, features=feats, heading=0.4)
    b = localize(scan, ring.scan_angles, m, sectors, ell, dataclasses.replace(paper, polish=True), features=feats,
                 heading=0.4)
    err_a, err_b = np.hypot(*(a.pose[:2] - pose[:2])), np.hypot(*(b.pose[:2] - pose[:2]))
    assert a.success and b.success and b.error < a.error
    assert err_a > 0.01 and err_b < 0.005
