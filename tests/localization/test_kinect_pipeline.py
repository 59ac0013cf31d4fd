"""Marker pipeline, grouping, pattern fit, fast path and tracker on synthetic Kinect frames."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.config import KinectConfig, MapConfig
from parcover_env.geometry import wrap_angle
from parcover_env.localization.kinect.estimate_model import estimate_fast, estimate_fast_all
from parcover_env.localization.kinect.pipeline import (
    PipelineParams,
    PoseEstimate,
    detect_markers,
    estimate_poses,
    fit_pattern,
    group_blobs,
    pipeline_stages,
)
from parcover_env.scenarios import load_scenario
from parcover_env.sensors.kinect import KinectFrame, KinectSensor, marker_pattern
from parcover_env.world.map_model import MapModel

OPEN = MapModel.from_config(MapConfig(size=(6.0, 6.0)))
PARAMS = PipelineParams()


def sensor(res=(640, 480), height=2.8, **kw) -> KinectSensor:
    return KinectSensor(KinectConfig(name="k", position=(3.0, 3.0), height=height, resolution=res, **kw),
                        0.15, 0.3, OPEN)


def tolerances(s: KinectSensor) -> tuple[float, float]:
    """Position / heading tolerance from the noise model: 1 px of marker centroid error at the
    robot's depth, plus half a disparity-quantization step of mean-depth error times the largest
    lateral lever (tan of half the horizontal FOV); heading: 1 px over the 10 cm marker spacing."""
    z = s.camera.C[2] - s.robot_height
    px = z / s.camera.focal
    q = z ** 2 / s.fb / 8
    return px + 0.54 * q / 2, px / 0.1


def match(poses: np.ndarray, est: list[PoseEstimate]) -> tuple[np.ndarray, np.ndarray]:
    """Position and heading error of each true pose's nearest estimate (inf when none)."""
    pos, head = np.full(len(poses), np.inf), np.full(len(poses), np.inf)
    for i, p in enumerate(poses):
        if est:
            e = min(est, key=lambda e: np.hypot(e.x - p[0], e.y - p[1]))
            pos[i] = np.hypot(e.x - p[0], e.y - p[1])
            head[i] = abs(wrap_angle(e.theta - p[2]))
    return pos, head


@pytest.mark.parametrize("res", [(640, 480), (320, 240)])
def test_known_poses_are_estimated_within_noise_tolerance(res):
    s = sensor(res)
    tol_p, tol_h = tolerances(s)
    rng = np.random.default_rng(3)
    missed = 0
    for _ in range(8):
        poses = np.array([[2.5, 2.7, 0.0], [3.1, 3.3, 0.0], [3.5, 2.6, 0.0]])
        poses[:, :2] += rng.uniform(-0.1, 0.1, (3, 2))
        poses[:, 2] = rng.uniform(-np.pi, np.pi, 3)
        est = estimate_poses(s.measure(poses, [True, True, True], rng), s.camera, PARAMS)
        pos, head = match(poses, est)
        found = pos < 0.2  # an estimate near the robot (the robots stand >= 0.4 m apart)
        missed += int((~found).sum())
        assert len(est) == found.sum()  # nothing spurious, nobody estimated twice
        assert np.all(pos[found] < tol_p) and np.all(head[found] < tol_h)
        assert all(e.n_markers >= 3 and abs(e.depth - 2.5) < 0.05 for e in est)
    # at 320 x 240 the markers are ~2 px discs and noise hides one now and then (1.3 % of the
    # robots over 150 frames of this scene); at 640 x 480 none is missed
    assert missed == 0 if res == (640, 480) else missed <= 2


def test_speckle_alone_gives_no_detection():
    s = sensor()
    rng = np.random.default_rng(4)
    poses = np.array([[3.0, 3.0, 0.0], [2.5, 2.8, 1.0]])
    for _ in range(10):
        f = s.measure(poses, [False, False], rng)  # robots without markers, speckle everywhere
        st = pipeline_stages(f.ir)
        assert (st["threshold"] > 0).sum() > 0  # some speckle clusters pass the threshold...
        # ...and the 3x3 opening removes them (a cluster on the image edge can survive it, OpenCV's
        # erosion counting the outside as set; blobs touching the border are dropped)
        assert not st["morphology"][2:-2, 2:-2].any()
        assert len(detect_markers(f.ir)) == 0
        assert estimate_poses(f, s.camera) == []
    assert len(detect_markers(f.ir, PipelineParams(otsu=True))) == 0


def test_two_touching_robots_are_separated():
    s = sensor()
    tol_p, tol_h = tolerances(s)
    rng = np.random.default_rng(5)
    for _ in range(10):
        a = np.array([3.0, 3.0])
        ang = rng.uniform(0, 2 * np.pi)
        b = a + 0.31 * np.array([np.cos(ang), np.sin(ang)])
        poses = np.array([[*a, rng.uniform(-np.pi, np.pi)], [*b, rng.uniform(-np.pi, np.pi)]])
        est = estimate_poses(s.measure(poses, [True, True], rng), s.camera, PARAMS)
        assert len(est) == 2
        pos, head = match(poses, est)
        assert pos.max() < tol_p and head.max() < tol_h


def test_robot_on_the_footprint_border_is_never_misplaced():
    s = sensor()
    tol_p, tol_h = tolerances(s)
    rng = np.random.default_rng(6)
    x_edge = 3.0 + 2.5 * np.tan(np.radians(57 / 2))  # footprint border on the marker plane
    seen = 0
    for dx in np.linspace(-0.2, 0.2, 17):
        pose = np.array([[x_edge + dx, 3.0, rng.uniform(-np.pi, np.pi)]])
        est = estimate_poses(s.measure(pose, [True], rng), s.camera, PARAMS)
        assert len(est) <= 1
        if est:
            seen += 1
            pos, head = match(pose, est)
            assert pos[0] < tol_p and head[0] < tol_h
        if dx <= -0.15:
            assert est, "a robot fully inside the image must be detected"
        if dx >= 0.05:
            assert not est, "fewer than 3 markers in view: no estimate"
    assert 3 <= seen < 17


def test_fit_pattern_recovers_pose_with_any_order_and_a_missing_marker():
    pat = marker_pattern(0.15)
    rng = np.random.default_rng(7)
    for _ in range(20):
        x, y, th = rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-np.pi, np.pi)
        c, s_ = np.cos(th), np.sin(th)
        world = pat @ np.array([[c, s_], [-s_, c]]) + (x, y)
        order = rng.permutation(4)[: rng.integers(3, 5)]
        pose, rms, assign = fit_pattern(world[order] + rng.normal(0, 0.001, (len(order), 2)), pat)
        assert np.hypot(pose[0] - x, pose[1] - y) < 0.005
        assert abs(wrap_angle(pose[2] - th)) < 0.05
        np.testing.assert_array_equal(assign, order)
        assert rms < 0.003
    with pytest.raises(ValueError, match="points"):
        fit_pattern(np.zeros((5, 2)), pat)


def test_group_blobs_splits_touching_robots_and_drops_strays():
    pat = marker_pattern(0.15)
    a = pat + (1.0, 1.0)
    b = -pat[:3] + (1.3, 1.0)  # rotated by pi, one marker missed
    stray = np.array([[3.0, 3.0]])
    pts = np.concatenate([a, b, stray])
    groups = sorted(group_blobs(pts, PARAMS), key=len)
    assert [sorted(g.tolist()) for g in groups] == [[4, 5, 6], [0, 1, 2, 3]]
    assert group_blobs(np.zeros((0, 2)), PARAMS) == []


def test_dropped_frames_and_bad_input():
    s = sensor(drop_rate=1.0)
    f = s.measure(np.array([[3.0, 3.0, 0.0]]), [True], np.random.default_rng(0))
    assert estimate_poses(f, s.camera) == []
    with pytest.raises(ValueError, match="uint8"):
        detect_markers(np.zeros((10, 10), float))
    bad = KinectFrame("k", np.zeros((10, 10), np.float32), np.zeros((10, 10), np.uint8))
    with pytest.raises(ValueError, match="shape"):
        estimate_poses(bad, s.camera)
    with pytest.raises(ValueError, match="odd"):
        PipelineParams(median_ksize=4)


def test_fast_path_agrees_with_full_pipeline():
    rng = np.random.default_rng(8)
    for res in ((640, 480), (320, 240)):
        s = sensor(res)
        full, fast = [], []
        n_full = n_fast = 0
        for _ in range(40):
            poses = np.array([[rng.uniform(2.2, 3.8), rng.uniform(2.4, 3.6), rng.uniform(-np.pi, np.pi)]])
            e1 = estimate_poses(s.measure(poses, [True], rng), s.camera, PARAMS)
            e2 = estimate_fast(s, poses, [True], rng)
            n_full, n_fast = n_full + len(e1), n_fast + len(e2)
            full += list(match(poses, e1)[0][np.isfinite(match(poses, e1)[0])])
            fast += list(match(poses, e2)[0][np.isfinite(match(poses, e2)[0])])
        assert abs(n_full - n_fast) <= 4
        m_full, m_fast = np.mean(full), np.mean(fast)
        assert 0.5 < m_fast / m_full < 2.0, (res, m_full, m_fast)


def test_fast_path_visibility():
    s = sensor()
    rng = np.random.default_rng(9)
    inside, outside = [3.0, 3.0, 0.3], [5.5, 3.0, 0.3]
    est = estimate_fast(s, np.array([inside, outside, inside]), [True, True, False], rng)
    assert [e.truth_index for e in est] == [0]
    small = sensor(height=3.6, res=(320, 240))
    assert estimate_fast(small, np.array([inside]), [True], rng) == []  # markers too small to survive
    mm = MapModel.from_config(MapConfig(size=(6.0, 6.0), walls=(((2.5, 2.0), (2.5, 4.0)),)))
    cfg = KinectConfig(name="k", position=(3.0, 3.0), height=2.8)
    tall = KinectSensor(cfg, 0.15, 0.3, mm, wall_height=2.0)
    behind = np.array([[2.2, 3.0, 0.0]])
    assert estimate_fast(tall, behind, [True], rng) == []  # hidden by the wall
    assert estimate_poses(tall.measure(behind, [True], rng), tall.camera) == []  # full pipeline agrees
    low = KinectSensor(cfg, 0.15, 0.3, mm, wall_height=0.5)
    assert len(estimate_fast(low, behind, [True], rng)) == 1


def test_write_kinect_views(tmp_path):
    from parcover_env.viz.kinect_views import write_kinect_views

    scen = load_scenario("office")
    paths = write_kinect_views(scen, tmp_path / "views", np.random.default_rng(0), duration=2.0)
    assert {p.name for p in paths} == {"kinect_depth.png", "kinect_ir.png", "kinect_pipeline.png",
                                       "kinect_hull.png", "kinect_trajectory.png"}
    for p in paths:
        assert p.stat().st_size > 1000 and p.read_bytes()[:4] == b"\x89PNG"


def test_fast_path_of_all_kinects_draws_like_one_call_per_kinect():
    """Two mis-mounted, dropping Kinects over robots in and out of view: the batched call gives the
    same estimates (same floats) as one call per Kinect from the same generator state."""
    cfgs = [KinectConfig(name=f"k{i}", position=(x, 3.0), height=2.8, drop_rate=0.2, mount_tilt_std_deg=1.0)
            for i, x in enumerate((2.5, 3.5))]
    sensors = [KinectSensor(c, 0.15, 0.3, OPEN) for c in cfgs]
    for k in sensors:
        k.mount(np.random.default_rng(5))
    assert all(k.true_camera is not k.camera for k in sensors)
    poses = np.array([[2.6, 3.1, 0.4], [3.4, 2.9, -2.0], [5.7, 0.3, 1.0], [3.0, 3.0, 3.0]])
    mask = [True, True, True, False]
    total = 0
    for seed in range(30):
        r1 = np.random.default_rng(seed)
        each = [estimate_fast(k, poses, mask, r1) for k in sensors]
        r2 = np.random.default_rng(seed)
        both = estimate_fast_all(sensors, poses, mask, r2)
        assert both == each and r1.random() == r2.random()
        total += sum(map(len, each))
    assert 30 < total < 4 * 30  # some frames dropped, the robot at (5.7, 0.3) and the unmarked one never seen


@pytest.mark.parametrize("seed", range(5))
def test_components_number_like_scipy(seed):
    from scipy.sparse.csgraph import connected_components

    from parcover_env.localization.kinect.pipeline import _components

    rng = np.random.default_rng(seed)
    pts = rng.uniform(0, 1, (12, 2))
    adj = np.linalg.norm(pts[:, None] - pts[None], axis=-1) <= 0.3
    n, comp = _components(adj)
    want_n, want = connected_components(adj, directed=False)
    assert n == want_n and np.array_equal(comp, want)
    assert _components(np.zeros((0, 0), bool))[0] == 0


def test_component_search_links_through_chains():
    from parcover_env.localization.kinect.pipeline import _components

    adj = np.eye(5, dtype=bool)
    for a, b in ((0, 3), (3, 4), (1, 2)):  # 0-3-4 and 1-2: found only by following the chain
        adj[a, b] = adj[b, a] = True
    n, comp = _components(adj)
    assert n == 2 and comp.tolist() == [0, 1, 1, 0, 0]


@pytest.mark.parametrize("seed", range(4))
def test_blobs_on_the_window_equal_the_whole_image(seed):
    """The window's blobs, boxes and centroids equal OpenCV's on the whole image (blobs on the
    border, too small and too big included), in raster order of the centroids."""
    import cv2

    from parcover_env.localization.kinect.pipeline import _blobs, find_blobs

    rng = np.random.default_rng(seed)
    ir = np.full((120, 160), 50, np.uint8)
    for _ in range(12):
        u, v = int(rng.integers(0, 150)), int(rng.integers(0, 110))
        ir[v:v + int(rng.integers(3, 9)), u:u + int(rng.integers(3, 9))] = 255
    ir[50:52, 70:72] = 255  # under the minimum area
    mask = pipeline_stages(ir, PARAMS)["morphology"]
    _, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    x, y, bw, bh, area = stats[1:].T
    h, w = mask.shape
    keep = (area >= PARAMS.min_area) & (area <= PARAMS.max_area_frac * h * w) & (x > 0) & (y > 0) \
        & (x + bw < w) & (y + bh < h)
    want = cents[1:][keep]
    want = want[np.lexsort((want[:, 0], want[:, 1]))]
    b = _blobs(ir, PARAMS)
    np.testing.assert_array_equal(b.centroids, want)  # bit for bit
    assert np.all(np.diff(b.centroids[:, 1]) >= 0)
    u0, v0 = b.origin
    for c, i, box in zip(b.centroids, b.ids, b.boxes, strict=True):
        vv, uu = np.nonzero(b.labels == i)
        n = len(uu)  # OpenCV: the sum of the coordinates over the area
        assert np.array_equal(c, [(uu.sum() + n * u0) / n, (vv.sum() + n * v0) / n])
        assert box.tolist() == [uu.min(), vv.min(), uu.max() + 1, vv.max() + 1]
    cents2, full, ids = find_blobs(ir, PARAMS)
    np.testing.assert_array_equal(cents2, want)
    for i, c in zip(ids, cents2, strict=True):  # the full label image marks the same pixels
        vv, uu = np.nonzero(full == i)
        assert np.allclose(c, [uu.mean(), vv.mean()], atol=1e-12)
    assert len(_blobs(np.zeros((30, 40), np.uint8), PARAMS).ids) == 0


def test_opencv_runs_on_one_thread_in_the_pipeline_and_the_setting_is_restored():
    import cv2

    from parcover_env.localization.kinect.pipeline import _one_cv_thread

    before = cv2.getNumThreads()
    cv2.setNumThreads(2)
    try:
        with _one_cv_thread():
            assert cv2.getNumThreads() == 1
        assert cv2.getNumThreads() == 2
        with pytest.raises(RuntimeError), _one_cv_thread():
            raise RuntimeError("restored on errors too")
        assert cv2.getNumThreads() == 2
    finally:
        cv2.setNumThreads(before)


@pytest.mark.parametrize("seed", range(4))
def test_fit_residual_is_the_rms_distance_of_the_fitted_pattern(seed):
    """The closed-form residual equals the RMS distance between the observed points and the
    assigned markers placed by the returned pose; no other assignment fits better."""
    import itertools

    pat = marker_pattern()
    rng = np.random.default_rng(seed)
    th = rng.uniform(-np.pi, np.pi)
    rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    idx = rng.permutation(4)[:3 + seed % 2]
    pts = pat[idx] @ rot.T + (2.0, -1.0) + rng.normal(0, 0.004, (len(idx), 2))
    pose, rms, assign = fit_pattern(pts, pat)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    placed = pat[assign] @ np.array([[c, -s], [s, c]]).T + pose[:2]
    assert rms == pytest.approx(np.sqrt(((placed - pts) ** 2).sum(-1).mean()), abs=1e-12)
    assert np.array_equal(assign, idx) and abs(wrap_angle(pose[2] - th)) < 0.1
    for other in itertools.permutations(range(4), len(idx)):  # brute force: the best assignment
        m = pat[list(other)]
        a, b = m - m.mean(0), pts - pts.mean(0)
        ang = np.arctan2((a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum(), (a * b).sum())
        r = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
        assert np.sqrt((((a @ r.T) - b) ** 2).sum(-1).mean()) >= rms - 1e-12


def test_blobs_on_the_border_or_outside_the_area_limits_are_dropped():
    """Hand-built mask through a one-stage pipeline (no median or morphology): 3 x 3 blobs touching
    each border, one pixel off each border, at the area limits."""
    from parcover_env.localization.kinect.pipeline import _blobs, find_blobs

    p = PipelineParams(median_ksize=1, open_ksize=1, close_ksize=1, min_area=9, max_area_frac=16 / (60 * 80))
    ir = np.zeros((60, 80), np.uint8)
    touching = [(0, 30), (57, 30), (20, 0), (20, 77)]  # (v, u) of the top-left pixel
    inside = [(1, 10), (56, 10), (30, 1), (30, 76)]
    for v, u in touching + inside:
        ir[v:v + 3, u:u + 3] = 255
    ir[40:42, 40:44] = 255  # 8 px: under min_area
    ir[10:14, 40:45] = 255  # 20 px: over max_area_frac * h * w = 16
    ir[45:49, 50:54] = 255  # 16 px: at the upper limit, kept
    ir[10:13, 60:63] = 255  # 9 px: at the lower limit, kept
    b = _blobs(ir, p)
    want = sorted([(v + 1.0, u + 1.0) for v, u in inside] + [(46.5, 51.5), (11.0, 61.0)])
    assert [(c[1], c[0]) for c in b.centroids] == want  # (v, u) raster order
    c, _, _ = find_blobs(ir, p)
    np.testing.assert_array_equal(c, b.centroids)
    p9 = PipelineParams(median_ksize=1, open_ksize=1, close_ksize=1, min_area=10, max_area_frac=0.5)
    assert find_blobs(ir, p9)[0].tolist() == [[42.0, 11.5], [51.5, 46.5]]  # the params reach find_blobs


def test_blobs_on_one_row_come_left_to_right():
    from parcover_env.localization.kinect.pipeline import find_blobs

    p = PipelineParams(median_ksize=1, open_ksize=1, close_ksize=1)
    ir = np.zeros((40, 60), np.uint8)
    ir[9:14, 40:43] = 255  # right, starts on row 9: OpenCV labels it first
    ir[10:13, 9:12] = 255  # left, starts a row later; the same centroid row 11: sorted first by column
    cents, labels, ids = find_blobs(ir, p)
    assert cents.tolist() == [[10.0, 11.0], [41.0, 11.0]]
    assert all(np.isclose(np.nonzero(labels == i)[1].mean(), c[0]) for i, c in zip(ids, cents, strict=True))


def test_may_see_all_edges_are_inside_on_every_side():
    from parcover_env.sensors.kinect import may_see_all

    s = sensor(res=(320, 240))
    x0, y0, x1, y1 = s.cull_box()
    for x, y in ((x0, 3.0), (x1, 3.0), (3.0, y0), (3.0, y1)):
        assert may_see_all([s], np.array([[x, y, 0.0]]), [True]).tolist() == [True]
        dx, dy = np.sign(x - 3.0) * 1e-9, np.sign(y - 3.0) * 1e-9
        assert may_see_all([s], np.array([[x + dx, y + dy, 0.0]]), [True]).tolist() == [False]


def test_fit_pattern_takes_two_to_four_points_of_shape_n_by_2():
    pat = marker_pattern()
    pose, rms, assign = fit_pattern(pat[[0, 2]] + (1.0, 2.0), pat)
    # the closed-form residual loses digits near 0 (a difference of squares): 1e-8 m here
    assert rms < 1e-7 and np.allclose(pose, [1.0, 2.0, 0.0], atol=1e-12) and sorted(assign) == [0, 2]
    for bad in (pat[:1], pat[:, :1], np.zeros((5, 2)), pat.reshape(-1)):
        with pytest.raises(ValueError, match="2..4 points"):
            fit_pattern(bad, pat)


def test_estimates_carry_the_frame_name_stamp_depth_and_residual():
    s = sensor(res=(640, 480))
    f = s.measure(np.array([[3.0, 3.0, 0.3]]), [True], np.random.default_rng(0), stamp=4.5)
    (e,) = estimate_poses(f, s.camera, PARAMS)
    assert (e.kinect, e.stamp, e.n_markers, e.truth_index) == ("k", 4.5, 4, None)
    assert 0 < e.residual <= PARAMS.max_residual and abs(e.depth - 2.5) < 0.02
    strict = PipelineParams(max_residual=e.residual * 0.999)
    assert estimate_poses(f, s.camera, strict) == []  # a fit above max_residual is rejected
    assert len(estimate_poses(f, s.camera, PipelineParams(max_residual=e.residual))) == 1  # at it: kept


def test_pipeline_stage_options():
    ir = np.full((40, 50), 60, np.uint8)
    ir[10:16, 10:16] = 250  # a marker blob
    ir[30, 30] = 255  # a speckle pixel: the median removes it
    st = pipeline_stages(ir, PARAMS)
    assert st["median"][30, 30] == 60 and st["threshold"][12, 12] == 255 and st["threshold"][30, 30] == 0
    raw = pipeline_stages(ir, PipelineParams(median_ksize=1, open_ksize=1, close_ksize=1))
    assert raw["median"][30, 30] == 255 and raw["morphology"][30, 30] == 255  # no median, no opening
    assert set(np.unique(st["morphology"])) == {0, 255} and st["morphology"][12, 12] == 255
    ir2 = ir.copy()
    ir2[10:16, 10:16] = 190  # under the fixed threshold 200 ...
    assert not pipeline_stages(ir2, PARAMS)["threshold"].any()
    otsu = pipeline_stages(ir2, PipelineParams(otsu=True, otsu_floor=150))["threshold"]
    assert otsu[12, 12] == 255 and otsu[0, 0] == 0  # ... Otsu splits 60 from 190 (raised to the 150 floor)
    assert not pipeline_stages(ir2, PipelineParams(otsu=True, otsu_floor=195))["threshold"].any()


