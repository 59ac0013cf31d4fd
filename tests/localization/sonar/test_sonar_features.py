"""Map features and characteristic points of synthetic scans in the T room."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import MapConfig, SonarConfig
from parcover_env.localization.sonar.features import characteristic_points, map_features
from parcover_env.localization.sonar.filter import filter_scan
from parcover_env.localization.sonar.sectors import visible_features
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.map_model import MapModel

T_ROOM = MapConfig(size=(4.0, 4.0), boundary=((1.2, 0.0), (2.8, 0.0), (2.8, 2.4), (4.0, 2.4), (4.0, 4.0),
                                              (0.0, 4.0), (0.0, 2.4), (1.2, 2.4)))
CORNERS = {(1.2, 0.0), (2.8, 0.0), (4.0, 2.4), (4.0, 4.0), (0.0, 4.0), (0.0, 2.4)}


def test_t_room_features_are_its_six_concave_corners():
    feats = map_features(MapModel.from_config(T_ROOM))
    assert {tuple(np.round(f.point, 6)) for f in feats} == CORNERS
    for f in feats:  # walls leave the corner along the boundary, normals point into free space
        assert np.allclose(np.linalg.norm(f.walls, axis=1), 1) and abs(f.walls[0] @ f.walls[1]) < 1e-9
        inward = f.point + 0.05 * f.normals.sum(axis=0)
        assert MapModel.from_config(T_ROOM).contains(inward[None])[0]


@pytest.mark.parametrize("pose", [(2.0, 3.2, 0.3), (2.0, 1.2, -1.0), (1.0, 3.0, 2.0), (3.3, 3.4, 0.0)])
def test_scan_maxima_are_the_visible_corners(pose):
    m = MapModel.from_config(T_ROOM)
    cfg = SonarConfig(model="ray", range_max=2.54, quantization=0.0)
    ring = SonarRing(cfg)
    scan = ring.scan(pose, m.segments, None, 0.165, None)
    pts = characteristic_points(scan, ring.scan_angles, cfg.range_max)
    seen = set()
    for i in pts.maxima:
        a = pose[2] + ring.scan_angles[i]
        xy = np.array(pose[:2]) + scan[i] * np.array([math.cos(a), math.sin(a)])
        near = [k for k in CORNERS if np.linalg.norm(xy - k) < 0.12 * max(scan[i], 1.0)]
        assert near, f"M point at {xy} is not a corner"
        seen.add(near[0])
    feats = map_features(m)
    vis = visible_features(np.array([pose[:2]]), m, feats, cfg.range_max)[0]
    expected = {tuple(np.round(f.point, 6)) for f, v in zip(feats, vis, strict=True) if v}
    assert seen == expected
    assert len(pts.labels) == 72 and set(pts.labels) <= set("mMDcf.")


def test_labels_far_jumps_and_bad_input():
    angles = np.radians(np.arange(12) * 30.0)
    r = np.array([1.0, 1.1, 1.3, 1.1, 1.0, 2.54, 2.54, 1.0, 1.0, 0.5, 0.5, 1.0])
    pts = characteristic_points(r, angles, 2.54)
    assert pts.labels[5] == "f" and pts.labels[6] == "f"
    assert pts.labels[2] == "M" and 0 in pts.minima or 4 in pts.minima
    assert pts.labels[8] == "D" and pts.labels[9] == "c"
    with pytest.raises(ValueError, match="equal-length"):
        characteristic_points(r, angles[:5], 2.54)


def test_filter_moves_long_faults_onto_the_wall():
    angles = np.radians(np.arange(72) * 5.0)
    r = np.minimum(1.0 / np.maximum(np.cos(angles), 1e-3), 2.54)  # a wall x = 1 in front
    r[np.cos(angles) <= 0] = 2.54
    bad = r.copy()
    bad[[2, 3, 70]] += 0.6  # multipath: readings too long
    out = filter_scan(np.minimum(bad, 2.54), angles, 2.54)
    np.testing.assert_allclose(out[[1, 2, 3, 70, 71]], r[[1, 2, 3, 70, 71]], atol=1e-6)
