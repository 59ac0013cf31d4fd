"""The compiled Kinect estimate model against its numpy formulas: the same detections from the same
draws, the same poses to rounding (the kernel projects coordinate by coordinate, numpy via BLAS)."""

from __future__ import annotations

import numpy as np
import pytest
from references import kinect as reference

import parcover_env
from parcover_env.localization.kinect.estimate_model import FastModel, FastNoise, estimate_fast_all


@pytest.mark.parametrize("scenario, remount", [("tree", False), ("tree", True), ("office", True)])
def test_kernel_equals_the_numpy_formulas(scenario, remount):
    env = parcover_env.parallel_env(scenario).unwrapped
    env.reset(seed=4)
    sensors = env.kinects.sensors
    if not remount:
        for s in sensors:
            s.true_camera = s.camera
    assert any(s.true_camera is not s.camera for s in sensors) == remount
    g = np.random.default_rng(1)
    lo, hi = np.array(env.map.bounds[:2]), np.array(env.map.bounds[2:])
    found = 0
    for trial in range(150):
        poses = np.column_stack([g.uniform(lo, hi, (12, 2)), g.uniform(-3.2, 3.2, 12)])
        mask = g.random(12) < 0.6
        a, b = np.random.default_rng(trial), np.random.default_rng(trial)
        got = estimate_fast_all(sensors, poses, mask, a)
        for s, est in zip(sensors, got, strict=True):
            want = reference.estimates(s, poses, mask, b)
            assert [e.truth_index for e in est] == [w[0] for w in want]
            for e, w in zip(est, want, strict=True):
                assert (e.x, e.y, e.theta) == pytest.approx(w[1:], abs=1e-12)
                assert e.n_markers == len(s.pattern) and e.kinect == s.name
            found += len(est)
        assert a.random() == b.random()  # the same draws
    assert found > 50


def test_frame_drops_and_several_kinects_in_one_call():
    env = parcover_env.parallel_env("tree").unwrapped
    env.reset(seed=2)
    sensors = env.kinects.sensors
    model = FastModel(sensors)
    model.kinects = model.kinects.copy()  # (the model's table is read-only)
    model.kinects["drop_rate"] = 1.0  # every frame dropped: one draw per Kinect, nothing seen
    poses = np.column_stack([env.world.poses()[:, :2], np.zeros(env.n_robots)])
    rng = np.random.default_rng(0)
    assert model.estimate([2, 0], poses, np.ones(env.n_robots, bool), rng) == [[], []]
    ref = np.random.default_rng(0)
    ref.random(2)
    assert rng.random() == ref.random()
    model.kinects["drop_rate"] = 0.0
    every = np.ones(env.n_robots, bool)
    seeing = [q for q, lst in enumerate(model.estimate(range(len(sensors)), poses, every, np.random.default_rng(0)))
              if lst]
    due = [seeing[0], (seeing[0] + 1) % len(sensors), seeing[0]]  # the same Kinect twice: two frames
    per = model.estimate(due, poses, every, np.random.default_rng(0))
    assert len(per) == 3 and len(per[0]) > 0 and len(per[2]) > 0
    for q, lst in zip(due, per, strict=True):
        assert all(e.kinect == sensors[q].name for e in lst)


def _seen_pose(sensors):
    """A robot pose under the first Kinect's camera centre (markers well inside the image)."""
    c = sensors[0].camera.C
    return np.array([[c[0], c[1], 0.3]])


def test_noise_scale_stamp_and_closing_limit():
    env = parcover_env.parallel_env("tree").unwrapped
    env.reset(seed=2)
    s = env.kinects.sensors[0]
    s.true_camera = s.camera
    pose = _seen_pose([s])
    quiet = FastNoise(pos_px=0.0, heading_px=0.0)
    est = estimate_fast_all([s], pose, [True], np.random.default_rng(0), noise=quiet, stamp=2.5)[0]
    assert len(est) == 1 and (est[0].x, est[0].y) == tuple(pose[0, :2])  # no noise: the true pose
    assert est[0].theta == pytest.approx(pose[0, 2], abs=1e-15)
    assert est[0].stamp == 2.5 and est[0].truth_index == 0
    loud = estimate_fast_all([s], pose, [True], np.random.default_rng(0), noise=FastNoise(pos_px=5.0))[0][0]
    assert 1e-4 < abs(loud.x - pose[0, 0]) < 0.2 and loud.stamp == 0.0
    from parcover_env.localization.kinect.estimate_model import estimate_fast

    assert estimate_fast(s, pose, [True], np.random.default_rng(0), noise=quiet, stamp=1.0)[0].stamp == 1.0
    # markers merge in the closing when their gap is under 3 px at the robot's depth
    model = FastModel([s])
    model.kinects = model.kinects.copy()
    z = s.camera.C[2] - s.robot_height
    px_per_m = s.camera.focal / z
    for gap_px, seen in ((2.6, False), (3.2, True)):
        model.kinects[0]["pattern_gap"] = gap_px / px_per_m
        assert bool(model.estimate([0], pose, np.array([True]), np.random.default_rng(0))[0]) == seen


def test_a_remounted_camera_is_not_served_from_the_old_cache():
    from parcover_env.localization.kinect.estimate_model import view_box

    env = parcover_env.parallel_env("tree").unwrapped
    env.reset(seed=2)
    s = env.kinects.sensors[0]
    s.true_camera = s.camera
    before = view_box(s)
    s.true_camera = s.camera.perturbed(0.0, 0.0, 0.0, 0.5)  # raised 0.5 m: a wider view
    after = view_box(s)
    assert after[0] < before[0] - 0.1 and after[2] > before[2] + 0.1
    s.true_camera = s.camera
    assert view_box(s) == before
