"""Synthetic overhead Kinect: static scene, robots, markers, noise model, inputs."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.config import KinectConfig, MapConfig
from parcover_env.sensors.kinect import BASELINE, KinectSensor, axial_sigma, marker_pattern
from parcover_env.world.map_model import MapModel

OPEN = MapModel.from_config(MapConfig(size=(6.0, 6.0)))


def sensor(height=2.8, res=(320, 240), mm=OPEN, **kw) -> KinectSensor:
    cfg = KinectConfig(name="k", position=(3.0, 3.0), height=height, resolution=res, **kw)
    return KinectSensor(cfg, 0.15, 0.3, mm)


def test_static_floor_depth_is_the_height_when_looking_down():
    s = sensor()
    assert s.static_depth.shape == (240, 320)
    np.testing.assert_allclose(s.static_depth, 2.8, atol=1e-9)
    assert np.all(s.static_class == KinectSensor.FLOOR)


def test_walls_are_raised_bodies():
    cfg = MapConfig(size=(6.0, 6.0), walls=(((3.0, 1.0), (3.0, 5.0)),), wall_thickness=0.2)
    mm = MapModel.from_config(cfg)
    s = KinectSensor(KinectConfig(name="k", position=(3.0, 3.0), height=2.8, resolution=(320, 240)),
                     0.15, 0.3, mm, wall_height=0.5)
    u, v = 159, 120  # image centre: straight down onto the wall top
    assert s.static_depth[v, u] == pytest.approx(2.3, abs=1e-6)
    assert s.static_class[v, u] == KinectSensor.WALL
    assert s.static_depth[v, 5] == pytest.approx(2.8)  # floor far from the wall
    wall_px = (s.static_class == KinectSensor.WALL).sum()
    # Wall top 0.2 m wide at 2.3 m: ~ 0.2 * f / 2.3 px wide, plus a visible side face.
    assert 0.2 * s.camera.focal / 2.3 * 240 * 0.9 < wall_px < 0.4 * s.camera.focal / 2.3 * 240


def test_robot_top_depth_owner_and_markers():
    s = sensor(res=(640, 480))
    pose = np.array([[3.0, 3.0, 0.4]])
    depth, owner, code = s.render_clean(pose, [True])
    uv, _ = s.camera.project(np.array([[3.0, 3.0, 0.3]]))
    u, v = np.rint(uv[0]).astype(int)
    assert depth[v, u] == pytest.approx(2.5)
    assert owner[v, u] == 0
    # Robot top area in pixels ~ pi (r f / z)^2.
    expected = np.pi * (0.15 * s.camera.focal / 2.5) ** 2
    assert abs((owner == 0).sum() - expected) < 0.05 * expected
    # Four saturated marker discs of radius 2 cm.
    marker_area = np.pi * (0.02 * s.camera.focal / 2.5) ** 2
    assert abs((code == 1).sum() - 4 * marker_area) < 0.2 * 4 * marker_area
    # A robot without markers carries none.
    _, _, code2 = s.render_clean(pose, [False])
    assert not code2.any()


def test_depth_missing_where_markers_saturate():
    rng = np.random.default_rng(1)
    s = sensor(res=(640, 480))
    pose = np.array([[3.0, 3.0, 0.4]])
    f = s.measure(pose, [True], rng)
    _, _, code = s.render_clean(pose, [True])
    assert np.all(f.depth[code > 0] == 0)
    assert np.all(f.ir[code == 1] == 255)
    assert f.depth.dtype == np.float32 and f.ir.dtype == np.uint8


def test_axial_noise_and_disparity_quantization():
    s = sensor(res=(640, 480))
    z = np.full((200, 200), 2.8)
    noisy = s.noisy_depth(z, np.random.default_rng(2))
    q = 2.8 ** 2 / s.fb / 8  # depth step of 1/8 px disparity
    expected = np.sqrt(axial_sigma(2.8) ** 2 + q ** 2 / 12)
    assert noisy.std() == pytest.approx(expected, rel=0.15)
    assert abs(noisy.mean() - 2.8) < 0.003
    disp = s.fb / noisy.astype(float) * 8
    np.testing.assert_allclose(disp, np.round(disp), atol=1e-2)  # multiples of 1/8 px
    assert s.fb == pytest.approx(s.camera.focal * BASELINE)
    small = sensor(res=(320, 240))
    assert small.fb == pytest.approx(small.camera.focal * 2 * BASELINE)  # native 640-wide focal


def test_range_limits_give_zero_depth():
    s = sensor(height=4.2, lateral_noise_px=0.0)  # floor at 4.2 m: beyond the 4.0 m range; robot top at 3.9 m: inside
    f = s.measure(np.array([[3.0, 3.0, 0.0]]), [False], np.random.default_rng(0))
    _, owner, _ = s.render_clean(np.array([[3.0, 3.0, 0.0]]), [False])
    assert np.mean(f.depth[owner < 0] == 0) > 0.99
    assert np.mean(f.depth[owner == 0] > 0) > 0.95
    s2 = sensor(height=1.0, range_min=0.8)
    f2 = s2.measure(np.array([[3.0, 3.0, 0.0]]), [False], np.random.default_rng(0))
    uv, _ = s2.camera.project(np.array([[3.0, 3.0, 0.3]]))
    u, v = np.rint(uv[0]).astype(int)
    assert f2.depth[v, u] == 0  # robot top at 0.7 m: closer than range_min
    assert f2.depth[0, 0] > 0


def test_measure_is_deterministic_and_drops_frames():
    s = sensor()
    poses = np.array([[3.0, 3.0, 0.0], [3.5, 3.2, 1.0]])
    a = s.measure(poses, [True, False], np.random.default_rng(5))
    b = s.measure(poses, [True, False], np.random.default_rng(5))
    np.testing.assert_array_equal(a.depth, b.depth)
    np.testing.assert_array_equal(a.ir, b.ir)
    d = sensor(drop_rate=1.0).measure(poses, [True, True], np.random.default_rng(0))
    assert d.dropped and not d.depth.any()


def test_bad_inputs_raise_value_error():
    s = sensor()
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="poses"):
        s.measure(np.zeros(3), [True], rng)
    with pytest.raises(ValueError, match="marker_mask"):
        s.measure(np.zeros((2, 3)), [True], rng)
    with pytest.raises(ValueError, match="NaN"):
        s.measure(np.full((1, 3), np.nan), [True], rng)
    with pytest.raises(ValueError, match="not above"):
        KinectSensor(KinectConfig(name="k", position=(3, 3), height=0.25), 0.15, 0.3, OPEN)
    with pytest.raises(ValueError):
        marker_pattern(0.01)


def test_marker_pattern_fits_on_the_robot_and_is_spread():
    for r in (0.1, 0.15, 0.3):
        pat = marker_pattern(r)
        assert np.linalg.norm(pat, axis=1).max() + 0.02 <= r + 1e-9
    pat = marker_pattern(0.15)
    d = np.linalg.norm(pat[:, None] - pat[None], axis=-1) + np.eye(4)
    assert d.min() >= 0.099


def test_view_culling_never_changes_a_frame():
    """Robots outside a Kinect's view are skipped before rendering: frames must be identical."""
    import parcover_env

    env = parcover_env.parallel_env("tree")
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    for sensor in env.kinects.sensors:
        x0, y0, x1, y1 = sensor.cull_box()
        assert x1 - x0 < 12 and y1 - y0 < 10  # the box really culls something on this map
        for _ in range(30):
            poses = np.c_[rng.uniform(0, 12, 15), rng.uniform(0, 10, 15), rng.uniform(-3, 3, 15)]
            culled = sensor.render_clean(poses, np.ones(15, bool))
            sensor._cull = (-np.inf, -np.inf, np.inf, np.inf)
            full = sensor.render_clean(poses, np.ones(15, bool))
            sensor._cull = None
            assert all(np.array_equal(a, b) for a, b in zip(culled, full))


def test_nominal_static_scene_is_rendered_once_per_map_and_shared_read_only(monkeypatch):
    calls = []
    original = KinectSensor._render_static

    def counting(self, map_model):
        calls.append(self.name)
        return original(self, map_model)

    monkeypatch.setattr(KinectSensor, "_render_static", counting)
    mm = MapModel.from_config(MapConfig(size=(5.0, 5.0)))
    cfg = KinectConfig(name="k", position=(2.5, 2.5), height=2.8, resolution=(80, 60))
    a, b = KinectSensor(cfg, 0.15, 0.3, mm), KinectSensor(cfg, 0.15, 0.3, mm)
    assert calls == ["k"] and a.static_depth is b.static_depth and not a.static_depth.flags.writeable
    KinectSensor(cfg, 0.15, 0.3, MapModel.from_config(MapConfig(size=(5.0, 5.0))))  # another map: rendered
    KinectSensor(KinectConfig(name="k", position=(2.0, 2.5), height=2.8, resolution=(80, 60)), 0.15, 0.3, mm)
    assert calls == ["k", "k", "k"]
    a.mount(np.random.default_rng(0))  # a mounted (perturbed) camera renders its own scene
    assert not np.array_equal(a.static_depth, b.static_depth) and calls == ["k"] * 4
    depth, _, _ = b.render_clean(np.array([[2.5, 2.5, 0.0]]), [True])  # drawing robots copies first
    assert depth.flags.writeable and np.isclose(b.static_depth, 2.8, atol=0.05).mean() > 0.9


@pytest.mark.parametrize("bits, var, top", [(12, 0.99968, 3.67), (16, 0.99998, 4.32)])
def test_normal_table_is_a_standard_normal_to_within_its_quantization(bits, var, top):
    from scipy.special import ndtr

    from parcover_env.sensors.kinect import normal_table

    t = normal_table(bits).astype(float)
    assert t.shape == (1 << bits,) and np.all(np.diff(t) > 0)  # an inverse CDF, no repeated values
    np.testing.assert_allclose(t, -t[::-1], atol=1e-6)  # symmetric
    assert abs(t.mean()) < 1e-7 and t.var() == pytest.approx(var, abs=2e-5)
    assert t.max() == pytest.approx(top, abs=0.01)  # the quantile of the last bin's middle
    for z in (-2.0, -1.0, 0.0, 0.5, 1.5):  # the table's CDF is the normal's to one bin
        assert abs(np.mean(t <= z) - ndtr(z)) <= 2.0 ** -bits + 1e-12
    assert normal_table(bits) is normal_table(bits) and not normal_table(bits).flags.writeable
    assert np.array_equal(normal_table(), normal_table(12))  # the default resolution


@pytest.mark.parametrize("lateral", [0.8, 0.0])
def test_frames_own_their_images_and_render_clean_returns_copies(lateral):
    """measure() keeps work images from frame to frame: no frame may share them, with or without
    lateral noise, and a pickled sensor leaves them behind."""
    import pickle

    s = sensor(lateral_noise_px=lateral)
    rng = np.random.default_rng(0)
    a = s.measure(np.array([[3.0, 3.0, 0.0]]), [True], rng)
    a_depth, a_ir = a.depth.copy(), a.ir.copy()
    b = s.measure(np.array([[3.4, 2.8, 1.0]]), [True], rng)
    np.testing.assert_array_equal(a.depth, a_depth)  # the second frame did not draw into the first
    np.testing.assert_array_equal(a.ir, a_ir)
    assert not np.array_equal(a.depth, b.depth)
    d1, o1, c1 = s.render_clean(np.array([[3.0, 3.0, 0.0]]), [True])
    d2, o2, c2 = s.render_clean(np.array([[2.6, 3.2, 0.0]]), [True])
    assert not np.array_equal(o1, o2) and not np.array_equal(c1, c2)  # copies, not the work images
    assert s._buffers and not pickle.loads(pickle.dumps(s))._buffers
    copy = pickle.loads(pickle.dumps(s))
    np.testing.assert_array_equal(copy.render_clean(np.array([[3.0, 3.0, 0.0]]), [True])[0], d1)


def test_frame_metadata_and_dropped_frames():
    s = sensor()
    poses = np.array([[3.0, 3.0, 0.0], [2.6, 3.1, 1.0]])
    rng = np.random.default_rng(0)
    f = s.measure(poses, [True, False], rng, stamp=1.25)
    assert (f.name, f.stamp, f.dropped, f.info) == ("k", 1.25, False, {"n_robots": 2})
    before = rng.bit_generator.state
    s.measure(poses, [True, False], rng)  # drop_rate 0: no drop draw (the frame's draws only)
    d = sensor(drop_rate=1.0).measure(poses, [True, False], np.random.default_rng(0), stamp=2.5)
    assert (d.name, d.stamp, d.dropped) == ("k", 2.5, True)
    assert d.depth.dtype == np.float32 and d.ir.dtype == np.uint8 and d.depth.shape == s.shape
    assert not d.depth.any() and not d.ir.any()
    r0, r1 = np.random.default_rng(5), np.random.default_rng(5)
    sensor().measure(poses, [True, False], r0)
    sensor(drop_rate=1e-9).measure(poses, [True, False], r1)  # a drop rate draws once more
    assert r0.bit_generator.state != r1.bit_generator.state and before != rng.bit_generator.state


def test_ir_levels_speckle_and_clusters():
    """Floor 55 and robot 75 plus uniform 0-31, speckle at ``speckle_density`` in 170-255, 2 x 3
    clusters at 255, markers at 255."""
    s = KinectSensor(KinectConfig(name="k", position=(3.0, 3.0), height=2.8, resolution=(320, 240)), 0.15, 0.3,
                     OPEN, speckle_density=0.0, speckle_clusters=0)
    poses = np.array([[3.0, 3.0, 0.0]])
    _, owner, code = s.render_clean(poses, [True])
    ir = s.render_ir(owner, code, np.random.default_rng(1)).astype(int)
    floor, robot = ir[owner < 0], ir[(owner >= 0) & (code != 1)]
    assert floor.min() == 55 and floor.max() == 86 and abs(floor.mean() - 70.5) < 0.2
    assert robot.min() == 75 and robot.max() == 106
    assert np.all(ir[code == 1] == 255) and (code == 1).sum() > 0
    dense = KinectSensor(s.cfg, 0.15, 0.3, OPEN, speckle_density=0.03, speckle_clusters=0)
    bright = dense.render_ir(owner, np.zeros_like(code), np.random.default_rng(2)) >= 170
    n = int(0.03 * 240 * 320)
    assert 0.95 * n < bright.sum() <= n  # some draws hit the same pixel
    spots = KinectSensor(s.cfg, 0.15, 0.3, OPEN, speckle_density=0.0, speckle_clusters=40)
    sat = spots.render_ir(owner, np.zeros_like(code), np.random.default_rng(3)) == 255
    assert 200 <= sat.sum() <= 240  # 40 clusters of 2 x 3 px, some overlapping
    import cv2

    _, _, st, _ = cv2.connectedComponentsWithStats(sat.astype(np.uint8), connectivity=8)
    assert np.any((st[1:, 2] == 3) & (st[1:, 3] == 2))  # a lone cluster is 3 wide, 2 high


def test_robot_boxes_hold_every_pixel_of_the_robot():
    """Drawing each robot over the whole image gives the same frame as over its box."""
    s = sensor()
    rng = np.random.default_rng(4)
    poses = np.column_stack([rng.uniform(2.0, 4.0, 6), rng.uniform(2.3, 3.7, 6), rng.uniform(-3, 3, 6)])
    boxes = s._robot_boxes(poses[:, :2])
    assert np.all(boxes[:, 0] >= 0) and np.all(boxes[:, 2] <= 320) and np.all(boxes[:, 3] <= 240)
    from parcover_env.sensors import kinect_kernels as kk

    out = []
    for bx in (boxes, np.tile([0, 0, 320, 240], (6, 1))):
        depth, owner, top = s.static_depth.copy(), np.full(s.shape, -1, np.int32), np.zeros(s.shape, bool)
        kk.draw_robots(depth, owner, top, s.rays, s.true_camera.C, bx.astype(np.int64), poses[:, :2].copy(),
                       0.15 ** 2, 0.3)
        out.append((depth, owner))
    np.testing.assert_array_equal(out[0][0], out[1][0])
    np.testing.assert_array_equal(out[0][1], out[1][1])
    for i, (u0, v0, u1, v1) in enumerate(boxes):  # tight: a robot alone reaches within 3-4 px of each side
        depth, owner, top = s.static_depth.copy(), np.full(s.shape, -1, np.int32), np.zeros(s.shape, bool)
        kk.draw_robots(depth, owner, top, s.rays, s.true_camera.C, np.array([[0, 0, 320, 240]]),
                       poses[i:i + 1, :2].copy(), 0.15 ** 2, 0.3)
        vv, uu = np.nonzero(owner == 0)
        assert 0 < uu.min() - u0 <= 3 and 0 < vv.min() - v0 <= 3 and 0 < u1 - uu.max() <= 4 and 0 < v1 - vv.max() <= 4
    behind = s._robot_boxes(np.array([[30.0, 3.0]]))  # far outside the view
    assert behind.tolist() == [[-1, -1, -1, -1]]
    assert s._robot_boxes(np.zeros((0, 2))).shape == (0, 4)
