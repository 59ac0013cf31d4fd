"""Kinect realism: mounting error shifts fixes by h tan(delta); lateral noise; ideal draws nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import ConfigError, KinectConfig, MapConfig
from parcover_env.geometry.camera import CameraModel
from parcover_env.localization.kinect.pipeline import PipelineParams, estimate_fast, estimate_poses
from parcover_env.sensors.kinect import KinectSensor
from parcover_env.world.map_model import MapModel

OPEN = MapModel.from_config(MapConfig(size=(6.0, 6.0)))


class _FixedDraws:
    """Stands in for the episode generator: returns the given standard normals, then zeros."""

    def __init__(self, values):
        self.values = np.asarray(values, dtype=float)

    def standard_normal(self, n):
        return self.values[:n]


@pytest.mark.parametrize("delta_deg", [0.5, 1.0, -2.0])
def test_pitch_error_shifts_a_floor_point_by_h_tan_delta(delta_deg):
    h = 2.8
    nominal = CameraModel.from_pose((3.0, 3.0), h, 90.0, 90.0)
    true = nominal.perturbed(math.radians(delta_deg), 0.0, 0.0, 0.0)
    below = np.array([[3.0, 3.0, 0.0]])  # the floor point right under the camera
    uv, _ = true.project(below)
    seen, _ = nominal.intersect_plane(uv, 0.0)  # where the pipeline (nominal camera) puts it
    shift = seen[0, :2] - below[0, :2]
    opposite, _ = nominal.intersect_plane(nominal.perturbed(-math.radians(delta_deg), 0, 0, 0).project(below)[0], 0)
    np.testing.assert_allclose(opposite[0, :2] - below[0, :2], -shift, atol=1e-9)  # the sign of delta matters
    assert np.hypot(*shift) == pytest.approx(h * abs(math.tan(math.radians(delta_deg))), rel=1e-6)
    assert abs(shift[0]) < 1e-9  # a pitch error (about the image x axis, world x here) moves along y
    # a height error alone leaves the point under the camera where it is
    raised, _ = nominal.intersect_plane(nominal.perturbed(0, 0, 0, 0.01).project(below)[0], 0.0)
    np.testing.assert_allclose(raised[0, :2], below[0, :2], atol=1e-9)


def test_mounted_sensor_fixes_carry_the_mounting_error():
    cfg = KinectConfig(name="k", position=(3.0, 3.0), height=2.8, resolution=(640, 480), mount_tilt_std_deg=1.0)
    s = KinectSensor(cfg, 0.15, 0.3, OPEN)
    s.mount(_FixedDraws([1.0, 0.0, 0.0, 0.0]))  # pitch = +1 sigma = 1 deg, nothing else
    assert s.true_camera is not s.camera
    want = (2.8 - 0.3) * math.tan(math.radians(1.0))  # markers on the robot top, 2.5 m below
    pose = np.array([[3.0, 3.0, 0.3]])
    rng = np.random.default_rng(0)
    fast = estimate_fast(s, pose, [True], rng)
    assert np.hypot(fast[0].x - 3.0, fast[0].y - 3.0) == pytest.approx(want, abs=0.005)
    frame = s.measure(pose, [True], rng)
    est = estimate_poses(frame, s.camera, PipelineParams(marker_height=0.3, robot_radius=0.15))
    assert np.hypot(est[0].x - 3.0, est[0].y - 3.0) == pytest.approx(want, abs=0.01)
    s.mount(_FixedDraws([0.0, 0.0, 0.0, 0.0]))  # a fresh episode, perfectly mounted by chance
    est = estimate_fast(s, pose, [True], rng)
    assert np.hypot(est[0].x - 3.0, est[0].y - 3.0) < 0.005


def test_ideal_mounting_draws_nothing_and_keeps_the_nominal_camera():
    cfg = KinectConfig(name="k", position=(3.0, 3.0), mount_tilt_std_deg=0, mount_yaw_std_deg=0,
                       mount_height_std=0)
    s = KinectSensor(cfg, 0.15, 0.3, OPEN)
    rng = np.random.default_rng(1)
    before = rng.bit_generator.state
    s.mount(rng)
    assert rng.bit_generator.state == before and s.true_camera is s.camera


def test_lateral_noise_frays_edges_not_flat_floor():
    s = KinectSensor(KinectConfig(name="k", position=(3.0, 3.0), lateral_noise_px=0.8), 0.15, 0.3, OPEN)
    depth, _, _ = s.render_clean(np.array([[3.0, 3.0, 0.0]]), [False])
    out = s.lateral_jitter(depth, np.random.default_rng(0))
    floor = np.isclose(depth, 2.8)
    interior = floor & np.roll(floor, 3, 0) & np.roll(floor, -3, 0) & np.roll(floor, 3, 1) & np.roll(floor, -3, 1)
    np.testing.assert_array_equal(out[interior], depth[interior])  # flat floor: unchanged
    top = np.isclose(depth, 2.5)
    changed = (out != depth) & (top | floor)
    assert 0 < changed.sum() < 0.05 * depth.size  # only near the robot's outline
    assert s.lateral_jitter(depth, np.random.default_rng(0)) is not depth
    off = KinectSensor(KinectConfig(name="k", position=(3.0, 3.0), lateral_noise_px=0.0), 0.15, 0.3, OPEN)
    assert off.lateral_jitter(depth, np.random.default_rng(0)) is depth


@pytest.mark.parametrize("key, value", [("mount_tilt_std_deg", -0.1), ("mount_yaw_std_deg", 20.0),
                                        ("mount_height_std", -0.01), ("lateral_noise_px", -1.0)])
def test_bad_mounting_errors_name_the_key(key, value):
    with pytest.raises(ConfigError, match=key):
        KinectConfig(name="k", position=(0.0, 0.0), **{key: value})
