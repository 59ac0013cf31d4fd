"""The Kinect's compiled per-pixel loops on hand-built images: depth noise, quantization, range,
lateral shift, and the robot drawing against a numpy reference of its formulas."""

from __future__ import annotations

import numpy as np
import pytest
from references import kinect as reference

from parcover_env.config import KinectConfig, MapConfig
from parcover_env.sensors import kinect_kernels as kk
from parcover_env.sensors.kinect import KinectSensor
from parcover_env.world.map_model import MapModel


def test_depth_noise_quantizes_disparity_and_applies_the_range():
    fb = np.float32(580.0 * 0.075)  # focal (px) x baseline (m)
    depth = np.array([[2.0, np.inf, 0.5, 5.0]])
    table = np.array([0.0, 1.0, -1.0], dtype=np.float32)  # draw -> standard-normal value
    draws = np.zeros((1, 4), dtype=np.uint16)
    out = np.empty((1, 4), dtype=np.float32)
    kk.depth_noise(depth, draws, table, 0, fb, np.float32(0.8), np.float32(4.0), out)
    # 2 m: disparity 43.5 / 2 = 21.75 px = 174 / 8 exactly: no quantization error
    assert out[0, 0] == np.float32(2.0)
    assert out[0, 1] == 0.0  # no surface
    assert out[0, 2] == 0.0 and out[0, 3] == 0.0  # nearer than 0.8 m, farther than 4 m
    # one sigma of noise at 2 m: sigma = 0.0012 + 0.0019 (2 - 0.4)^2 = 0.006064 m, then quantized
    for draw, sign in ((1, 1.0), (2, -1.0)):
        kk.depth_noise(depth[:, :1], np.full((1, 1), draw << 4, np.uint16), table, 4, fb, np.float32(0.8),
                       np.float32(4.0), out[:, :1])
        z = 2.0 + sign * 0.006064
        want = float(fb) / (np.rint(float(fb) / z * 8.0) / 8.0)
        assert abs(out[0, 0] - want) < 1e-5 and out[0, 0] != np.float32(2.0)


def test_lateral_shift_reads_the_displaced_pixel_clamped_to_the_image():
    depth = np.arange(12, dtype=np.float32).reshape(3, 4)
    table = np.array([0, 1, -1, 5], dtype=np.int32)  # draw index -> offset
    draws = np.zeros((2, 3, 4), dtype=np.uint16)
    draws[1, 0, 0] = 1  # pixel (0, 0): one column right -> depth[0, 1]
    draws[0, 0, 1] = 2  # pixel (0, 1): one row up, clamped -> depth[0, 1]
    draws[0, 1, 3] = 3  # pixel (1, 3): five rows down, clamped to row 2 -> depth[2, 3]
    out = np.empty_like(depth)
    kk.lateral_shift(depth, draws, table, out)
    want = depth.copy()
    want[0, 0], want[0, 1], want[1, 3] = depth[0, 1], depth[0, 1], depth[2, 3]
    np.testing.assert_array_equal(out, want)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_robot_drawing_equals_the_numpy_reference_bit_for_bit(seed):
    """Touching and overlapping robots (occlusion order), robots cut by the image border, marker
    carriers and robots without markers, a tilted (mis-mounted) camera."""
    mm = MapModel.from_config(MapConfig(size=(6.0, 6.0), walls=(((1.9, 1.0), (1.9, 5.0)),)))
    s = KinectSensor(KinectConfig(name="k", position=(3.0, 3.0), height=2.6, resolution=(320, 240)), 0.15, 0.3, mm)
    rng = np.random.default_rng(seed)
    s.mount(rng)
    poses = np.column_stack([rng.uniform(2.2, 4.0, 12), rng.uniform(2.3, 3.7, 12), rng.uniform(-np.pi, np.pi, 12)])
    poses[1, :2] = poses[0, :2] + (0.25, 0.05)  # overlapping cylinders: the nearer one wins
    poses[2, :2] = (3.0 + 1.3, 3.0)  # cut by the image border
    mask = rng.random(12) < 0.6
    mask[:2] = True
    depth, owner, code = s.render_clean(poses, mask)
    want = reference.render(s, poses, mask)
    np.testing.assert_array_equal(depth, want[0])
    np.testing.assert_array_equal(owner, want[1])
    np.testing.assert_array_equal(code, want[2])
    assert (code == 1).sum() > 0 and (code == 2).sum() > 0 and len(np.unique(owner)) > 6


def test_ir_levels_put_the_robot_level_where_a_robot_is_seen_plus_the_noise():
    static = np.array([[40, 55, 55]], dtype=np.int16)
    owner = np.array([[-1, 3, -1]], dtype=np.int32)
    noise = np.array([[255, 7, 64]], dtype=np.uint8)  # uniform bytes -> 0-31: 31, 0, 8
    out = np.empty((1, 3), dtype=np.uint8)
    kk.ir_levels(static, owner, noise, 75, out)
    assert out.tolist() == [[71, 75, 63]]
