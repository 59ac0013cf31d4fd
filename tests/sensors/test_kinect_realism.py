"""Kinect realism: mounting error shifts fixes by h tan(delta); lateral noise; ideal draws nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import ConfigError, KinectConfig, MapConfig
from parcover_env.geometry.camera import CameraModel
from parcover_env.localization.kinect.estimate_model import estimate_fast
from parcover_env.localization.kinect.pipeline import PipelineParams, estimate_poses
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


@pytest.mark.parametrize("sigma", [0.5, 0.8, 2.0])
def test_rounded_normal_table_has_the_rounded_normal_probabilities(sigma):
    from scipy.special import ndtr

    from parcover_env.sensors.kinect import rounded_normal_table

    table = rounded_normal_table(sigma)
    assert table.shape == (1 << 16,) and np.all(np.diff(table) >= 0)  # an inverse CDF
    for k in range(-3, 4):
        exact = ndtr((k + 0.5) / sigma) - ndtr((k - 0.5) / sigma)
        assert abs(np.mean(table == k) - exact) <= 2.0 ** -16 + 1e-12, k
    assert table.sum() == 0  # symmetric
    with pytest.raises(ValueError, match="sigma"):
        rounded_normal_table(0.0)


def test_lateral_offsets_have_the_configured_spread_and_clamp_at_the_border():
    from scipy.special import ndtr

    s = KinectSensor(KinectConfig(name="k", position=(3.0, 3.0), lateral_noise_px=0.8), 0.15, 0.3, OPEN)
    h, w = s.shape
    cols = np.broadcast_to(np.arange(w, dtype=float), (h, w))  # depth = column index: shows du
    rows = np.broadcast_to(np.arange(h, dtype=float)[:, None], (h, w))
    rng = np.random.default_rng(3)
    du = s.lateral_jitter(cols, rng) - cols
    dv = s.lateral_jitter(rows, rng) - rows
    k = np.arange(-8, 9)
    p = ndtr((k + 0.5) / 0.8) - ndtr((k - 0.5) / 0.8)
    var = float((p * k**2).sum())  # 0.8^2 + 1/12 approximately: 0.722
    inner = (slice(5, h - 5), slice(5, w - 5))
    assert du[inner].var() == pytest.approx(var, rel=0.03) and dv[inner].var() == pytest.approx(var, rel=0.03)
    assert abs(du[inner].mean()) < 0.01 and np.isclose(np.mean(du[inner] == 0), p[8], atol=0.005)
    assert du[:, 0].min() == 0 and du[:, -1].max() == 0  # clamped to the image, never wrapped


def test_may_see_only_marker_carriers_inside_the_view_box():
    s = KinectSensor(KinectConfig(name="k", position=(3.0, 3.0), height=2.8), 0.15, 0.3, OPEN)
    x0, y0, x1, y1 = s.cull_box()
    inside, outside = [3.0, 3.0, 0.0], [x1 + 0.05, 3.0, 0.0]
    assert s.may_see(np.array([inside]), [True])
    assert not s.may_see(np.array([inside]), [False])  # a follower carries no markers
    assert not s.may_see(np.array([outside]), [True])
    assert s.may_see(np.array([outside, inside]), [False, True])


def test_may_see_all_answers_for_each_sensor_in_one_call():
    from parcover_env.sensors.kinect import may_see_all

    a = KinectSensor(KinectConfig(name="a", position=(2.0, 3.0), height=2.8), 0.15, 0.3, OPEN)
    b = KinectSensor(KinectConfig(name="b", position=(7.0, 3.0), height=2.8), 0.15, 0.3, OPEN)
    ax1, bx0 = a.cull_box()[2], b.cull_box()[0]
    assert ax1 < bx0  # two separate views
    poses = np.array([[2.0, 3.0, 0.0], [7.0, 3.0, 0.0]])
    assert may_see_all([a, b], poses, [True, False]).tolist() == [True, False]
    assert may_see_all([a, b], poses, [False, True]).tolist() == [False, True]
    assert may_see_all([b, a], poses, [True, True]).tolist() == [True, True]
    edge = np.array([[ax1, 3.0, 0.0]])  # on the box's edge: inside (the boxes are closed)
    assert may_see_all([a, b], edge, [True]).tolist() == [True, False]
    assert may_see_all([], poses, [True, True]).shape == (0,)
    with pytest.raises(ValueError, match="marker_mask"):
        may_see_all([a], poses, [True])


def test_frames_mode_renders_only_kinects_that_may_see_a_leader():
    import parcover_env

    env = parcover_env.parallel_env("tree", overrides={"observation": {"kinect": "frames"}})
    env.reset(seed=0)
    env.step({a: np.zeros(2, np.float32) for a in env.agents})
    poses, markers = env.true_poses(), env.team.leader & env.scenario.robot.markers
    expected = {s.name for s in env.kinects.sensors if s.may_see(poses, markers)}
    assert expected and expected != {s.name for s in env.kinects.sensors}  # some, not all, on tree's start
    assert set(env.kinect_frames()) == expected
