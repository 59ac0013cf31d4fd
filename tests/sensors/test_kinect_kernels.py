"""The Kinect's compiled per-pixel loops on hand-built images: depth noise, quantization, range,
lateral shift, and the robot drawing against a numpy reference of its formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest

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


def _render_reference(s: KinectSensor, poses: np.ndarray, marker_mask: np.ndarray):
    """Robots and marker codes drawn with numpy, one robot at a time, from the formulas of
    :meth:`KinectSensor.render_clean` (the code the compiled loops replaced)."""
    depth = s.static_depth.copy()
    owner = np.full(s.shape, -1, dtype=np.int32)
    top = np.zeros(s.shape, dtype=bool)
    C, r2 = s.true_camera.C, s.robot_radius ** 2
    boxes = s._robot_boxes(poses[:, :2])
    for i, (x, y, _) in enumerate(poses):
        if boxes[i, 0] < 0:
            continue
        u0, v0, u1, v1 = boxes[i]
        D = s.rays[v0:v1, u0:u1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t_top = (s.robot_height - C[2]) / D[..., 2]
            px, py = C[0] + D[..., 0] * t_top - x, C[1] + D[..., 1] * t_top - y
            on_top = (t_top > 0) & (px * px + py * py <= r2)
            ox, oy = C[0] - x, C[1] - y
            a = D[..., 0] ** 2 + D[..., 1] ** 2
            b = ox * D[..., 0] + oy * D[..., 1]
            disc = b * b - a * (ox * ox + oy * oy - r2)
            t_side = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
            z_side = C[2] + t_side * D[..., 2]
        on_side = (disc > 0) & (t_side > 0) & (z_side >= 0) & (z_side <= s.robot_height)
        t = np.minimum(np.where(on_top, t_top, np.inf), np.where(on_side, t_side, np.inf))
        sub = depth[v0:v1, u0:u1]
        closer = t < sub
        sub[closer] = t[closer]
        owner[v0:v1, u0:u1][closer] = i
        top[v0:v1, u0:u1][closer] = on_top[closer] & (t_top[closer] <= t[closer])
    code = np.zeros(s.shape, dtype=np.uint8)
    for i, (x, y, th) in enumerate(poses):
        if not marker_mask[i] or boxes[i, 0] < 0:
            continue
        u0, v0, u1, v1 = boxes[i]
        mine = (owner[v0:v1, u0:u1] == i) & top[v0:v1, u0:u1]
        t = depth[v0:v1, u0:u1][mine]
        D = s.rays[v0:v1, u0:u1][mine]
        p = C[:2] + D[:, :2] * t[:, None] - (x, y)
        c, sn = math.cos(th), math.sin(th)
        q = np.stack([c * p[:, 0] + sn * p[:, 1], -sn * p[:, 0] + c * p[:, 1]], axis=1)
        d2 = ((q[:, None, :] - s.pattern[None]) ** 2).sum(-1).min(axis=1)
        code[v0:v1, u0:u1][mine] = np.where(d2 <= s.marker_radius ** 2, 1,
                                            np.where(d2 <= (s.marker_radius * s.missing_factor) ** 2, 2, 0))
    return depth, owner, code


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
    want = _render_reference(s, poses, mask)
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
