"""The Kinect's compiled per-pixel loops on hand-built images: depth noise, quantization, range, lateral shift."""

from __future__ import annotations

import numpy as np

from parcover_env.sensors import _kinect_kernels as kk


def test_depth_noise_quantizes_disparity_and_applies_the_range():
    fb = np.float32(580.0 * 0.075)  # focal (px) x baseline (m)
    depth = np.array([[2.0, np.inf, 0.5, 5.0]])
    normal = np.zeros((1, 4), dtype=np.float32)
    out = np.empty((1, 4), dtype=np.float32)
    kk.depth_noise(depth, normal, fb, np.float32(0.8), np.float32(4.0), out)
    # 2 m: disparity 43.5 / 2 = 21.75 px = 174 / 8 exactly: no quantization error
    assert out[0, 0] == np.float32(2.0)
    assert out[0, 1] == 0.0  # no surface
    assert out[0, 2] == 0.0 and out[0, 3] == 0.0  # nearer than 0.8 m, farther than 4 m
    # one sigma of noise at 2 m: sigma = 0.0012 + 0.0019 (2 - 0.4)^2 = 0.006064 m, then quantized
    kk.depth_noise(depth[:, :1], np.ones((1, 1), dtype=np.float32), fb, np.float32(0.8), np.float32(4.0), out[:, :1])
    z = 2.0 + 0.006064
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
