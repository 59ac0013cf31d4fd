"""The Kinect systems of K worlds in one batch (kinect/batch_update.py, estimate_kernel.candidates):
the same estimates from the same draws as the per-world compiled model, and a pinned hand-built case."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import parcover_env
from parcover_env.localization.kinect import estimate_kernel
from parcover_env.localization.kinect.batch_update import fast_estimates, update_systems
from parcover_env.localization.kinect.estimate_model import FastModel, FastNoise


def _systems(seeds):
    """Kinect systems of ``tree`` worlds mounted by different seeds, sharing one static scene (as
    the batched worlds do)."""
    systems = []
    for seed in seeds:
        env = parcover_env.parallel_env("tree").unwrapped
        env.reset(seed=seed)
        systems.append(env.kinects)
    for s in systems[1:]:
        s.fast.depths = systems[0].fast.depths
    return systems, env.map.bounds


@pytest.mark.parametrize("drop_rate", [None, 0.3])
def test_fast_estimates_of_two_worlds_are_the_per_world_model(drop_rate):
    systems, bounds = _systems([4, 5])
    if drop_rate is not None:
        for s in systems:
            s.fast.kinects = s.fast.kinects.copy()
            s.fast.kinects["drop_rate"] = drop_rate
    n_kinects = len(systems[0].sensors)
    g = np.random.default_rng(1)
    lo, hi = np.array(bounds[:2]), np.array(bounds[2:])
    found = 0
    for trial in range(100):
        poses = np.stack([np.column_stack([g.uniform(lo, hi, (12, 2)), g.uniform(-3.2, 3.2, 12)]) for _ in range(2)])
        mask = g.random((2, 12)) < 0.6
        due = g.random((2, n_kinects)) < 0.7
        rngs = [np.random.default_rng(trial), np.random.default_rng(1000 + trial)]
        got = fast_estimates(systems, due, poses, mask, [0.5, 0.7], rngs)
        for b, s in enumerate(systems):
            ref = np.random.default_rng(trial if b == 0 else 1000 + trial)
            want = [e for lst in s.fast.estimate(np.flatnonzero(due[b]), poses[b], mask[b], ref, stamp=[0.5, 0.7][b])
                    for e in lst]
            assert got[b] == want  # the same estimates (dataclasses: every field, exact floats)
            assert rngs[b].random() == ref.random()  # the same draws
            found += len(want)
        alone = fast_estimates(systems[1:], due[1:], poses[1:], mask[1:], [0.7], [np.random.default_rng(1000 + trial)])
        assert alone[0] == got[1]  # K = 1 of the same code
    assert found > 40


@pytest.mark.parametrize("shared", [False, True])
def test_update_systems_of_two_worlds_is_update_of_each(shared):
    systems, _ = _systems([6, 7])
    alone = [copy.deepcopy(s) for s in systems]
    ticks = np.stack([s.next_tick for s in systems]) if shared else None
    if shared:  # the systems' next_tick as rows of one block (as the act phase's shared rows give them)
        for s, row in zip(systems, ticks, strict=True):
            s.next_tick = row
    poses = np.array([[[3.0, 4.0, 0.1], [5.0, 9.0, 1.0], [6.0, 9.5, -2.0]],
                      [[3.2, 4.1, 0.2], [5.5, 9.0, 0.0], [7.0, 9.0, 3.0]]])
    markers = np.array([[True, False, True], [True, True, False]])
    predicted = poses + 0.02
    fixes = 0
    for step in range(10):
        t = 0.1 * (step + 1)
        rngs = [np.random.default_rng(step), np.random.default_rng(50 + step)]
        got = update_systems(systems, [t, t], poses, markers, predicted, rngs, ticks=ticks)
        for k, s in enumerate(alone):
            want = s.update(t, poses[k], markers[k], predicted[k], np.random.default_rng(50 * k + step))
            assert got[k].keys() == want.keys()
            for i in want:
                np.testing.assert_array_equal(got[k][i], want[i])
            np.testing.assert_array_equal(systems[k].next_tick, s.next_tick)
            assert not shared or systems[k].next_tick.base is ticks  # still the block's rows
            fixes += len(want)
    assert fixes > 0


def test_candidates_pinned_under_a_downward_kinect():
    """Office's Kinect A looks straight down from (1.6, 2.3, 3.9) m: a carrier in its view is seen at
    its true pose (a nominal mount), with the error sigmas of the fast noise model at its depth (the
    marker plane is parallel to the image: every marker at 3.6 m); a non-carrier, a carrier off the
    image and one under the top of the office's wall block (x 1.4-3.2 m, y 1.8-3.2 m) are not."""
    env = parcover_env.parallel_env("office").unwrapped
    env.reset(seed=0)
    sensor = env.kinects.sensors[0]
    sensor.true_camera = sensor.camera  # nominal mount: the pipeline reconstructs the true pose
    model = FastModel([sensor])
    poses = np.array([[[0.8, 1.0, 0.3], [0.9, 1.2, -1.0], [40.0, 40.0, 0.0], [2.0, 2.4, 0.0]]])
    carriers = np.array([[True, False, True, True]])
    out_row, out_index, out_geom = np.empty(4, np.int64), np.empty(4, np.int64), np.empty((4, 7))
    row_drop = np.full(1, np.nan)
    n = estimate_kernel.candidates(np.zeros((3, 1), np.int64), poses, carriers, model.kinects, model.pattern,
                                   model.depths, model.noise, row_drop, out_row, out_index, out_geom)
    assert n == 1 and out_row[0] == 0 and out_index[0] == 0 and row_drop[0] == sensor.cfg.drop_rate
    p_det, merged, sigma_xy, sigma_th, x, y, th = out_geom[0]
    assert (x, y, th) == (0.8, 1.0, 0.3)
    fu, depth, nz = sensor.camera.K[0, 0], 3.9 - sensor.robot_height, FastNoise()
    mpp = depth / fu * (640 / sensor.shape[1]) ** nz.res_exponent  # metres per pixel at the markers
    assert sigma_xy == pytest.approx(nz.pos_px * mpp, rel=1e-9)
    assert sigma_th == pytest.approx(nz.heading_px * mpp / np.ptp(sensor.pattern[:, 0]), rel=1e-9)
    r_px = sensor.marker_radius * fu / depth
    assert p_det == pytest.approx(min(max((r_px - nz.r_px_min) / (nz.r_px_full - nz.r_px_min), 0.0), 1.0), rel=1e-9)
    assert p_det > 0.5 and merged == 0.0


def test_tracker_matches_the_optimal_assignment_with_or_without_the_solver():
    """The tracker skips the assignment solver when no estimate is within the gate of two robots (nor
    a robot of two estimates): its matches stay those of the minimum-cost assignment."""
    from scipy.optimize import linear_sum_assignment

    from parcover_env.localization.kinect.pipeline import PoseEstimate
    from parcover_env.localization.kinect.tracker import KinectTracker

    g = np.random.default_rng(0)
    crowded = 0
    for _ in range(300):
        n_est, n_ref = g.integers(1, 5), g.integers(1, 5)
        xy = g.uniform(0, 1.5, (n_est, 2))
        ests = [PoseEstimate(x, y, 0.0, 4) for x, y in xy]
        ref = {int(i): np.array([*g.uniform(0, 1.5, 2), 0.0]) for i in g.choice(10, n_ref, replace=False)}
        tracker = KinectTracker(gate=0.3, fuse_radius=0.01)
        got = tracker.update([ests], ref)
        fused = tracker.fuse(ests)
        ids = list(ref)
        cost = np.array([[np.hypot(*(f[:2] - ref[k][:2])) for k in ids] for f in fused])
        rows, cols = linear_sum_assignment(np.where(cost <= 0.3, cost, 1e6))
        want = {ids[c]: fused[r] for r, c in zip(rows, cols, strict=True) if cost[r, c] <= 0.3}
        assert list(got) == list(want)  # the same robots, in the same order
        for k in want:
            np.testing.assert_array_equal(got[k], want[k])
        inside = cost <= 0.3
        crowded += bool(inside.sum(axis=0).max() > 1 or inside.sum(axis=1).max() > 1)
    assert 20 < crowded < 280  # both paths taken


def _office_system(kinect: str = "estimate"):
    """Office's Kinect system (one Kinect A at 15 Hz looking straight down), mounted as designed."""
    a = {"name": "A", "position": [1.6, 2.3], "height": 3.9, "pitch_deg": 90, "yaw_deg": 0, "resolution": [640, 480],
         "rate_hz": 15, "mount_tilt_std_deg": 0.0, "mount_yaw_std_deg": 0.0, "mount_height_std": 0.0}
    env = parcover_env.parallel_env("office", overrides={"observation": {"kinect": kinect}, "kinects": [a]}).unwrapped
    env.reset(seed=0)
    assert all(s.true_camera is s.camera for s in env.kinects.sensors)
    return env.kinects


@pytest.mark.parametrize("kinect", ["estimate", "frames"])
def test_update_systems_pinned_on_office(kinect):
    """A due Kinect fixes the visible carrier matched by its predicted pose (to the fast model's sub-mm
    noise, or the pipeline's mm) and schedules its next frame one period on; a Kinect not due, or no
    carrier at all, draws nothing and fixes nobody."""
    system = _office_system(kinect)
    period = 1.0 / 15.0
    true = np.array([[[0.8, 1.0, 0.3], [0.9, 1.6, -1.0]]])
    predicted = true + np.array([0.05, -0.04, 0.02])  # dead reckoning a few cm off: within the gate
    rng = np.random.default_rng(0)
    fixes = update_systems([system], [0.1], true, np.array([[True, False]]), predicted, [rng])[0]
    assert list(fixes) == [0] and system.last_fixes is fixes  # robot 1 carries no markers
    np.testing.assert_allclose(fixes[0], true[0, 0], atol=5e-3 if kinect == "frames" else 1e-3)
    assert system.next_tick.tolist() == [0.1 + period]
    if system.fast is not None:  # frames may drop from now on: still no draw without a carrier
        system.fast.kinects = system.fast.kinects.copy()
        system.fast.kinects["drop_rate"] = 0.5
    state = copy.deepcopy(rng.bit_generator.state)
    assert update_systems([system], [0.15], true, np.array([[True, True]]), predicted, [rng]) == [{}]  # not due
    assert system.next_tick.tolist() == [0.1 + period] and system.last_fixes == {}
    assert update_systems([system], [0.2], true, np.zeros((1, 2), bool), predicted, [rng]) == [{}]  # no carrier
    assert system.next_tick.tolist() == [0.2 + period]
    assert rng.bit_generator.state == state  # nothing drawn
    far = predicted + np.array([1.5, 0.0, 0.0])  # predicted beyond the gate (1 m): no match, no fix
    assert update_systems([system], [0.3], true, np.array([[True, False]]), far, [rng]) == [{}]


def test_match_kernel_pinned_on_hand_built_worlds():
    """World 0: two estimates far apart (the 4-marker one first: the tracker's order), each fused to
    itself (``(w x) / w``, heading wrapped) and matched to the carrier within the gate; world 1: two
    estimates within the fuse radius, world 2: one within the gate of two carriers, world 3: one at the
    gate to 1e-12, world 4: two at the fuse radius to 1e-12: left to the tracker."""
    from parcover_env.localization.kinect import track_kernel

    est = np.array([[0.1, 1.0, 0.5, 3], [4.0, 4.0, 3.5, 4],  # world 0
                    [2.0, 2.0, 0.0, 4], [2.05, 2.0, 0.0, 4],  # world 1
                    [3.0, 3.0, 0.0, 4],  # world 2
                    [5.0, 5.0, 0.0, 4],  # world 3
                    [6.0, 6.0, 0.0, 4], [6.0, 6.0 + 0.12 * (1 + 1e-12), 0.0, 4]], dtype=float)  # world 4
    starts = np.array([0, 2, 4, 5, 6, 8])
    ref = np.zeros((5, 3, 2))
    ref[0] = [[0.1 + 0.2995, 1.0], [9.0, 9.0], [4.0, 3.8]]
    ref[1] = [[2.0, 2.0], [0.0, 0.0], [0.0, 0.0]]
    ref[2] = [[3.1, 3.0], [2.9, 3.0], [0.0, 0.0]]
    ref[3] = [[5.3 + 1e-12, 5.0], [0.0, 0.0], [0.0, 0.0]]
    ref[4] = [[9.0, 9.0], [0.0, 0.0], [0.0, 0.0]]
    carriers = np.array([[True, True, True], [True, False, False], [True, True, False], [True, False, False],
                         [True, False, False]])
    fused, robot, status = np.full((8, 3), np.nan), np.full(8, -9), np.full(5, -9)
    track_kernel.match(est, starts, ref, carriers, 0.3, 0.12, fused, robot, status)
    assert status.tolist() == [0, 1, 1, 1, 1]
    assert fused[1, 0] == (3.0 * 0.1) / 3.0 != 0.1  # the tracker's weighted mean, in its floats
    np.testing.assert_allclose(fused[:2], [[4.0, 4.0, 3.5 - 2 * np.pi], [0.1, 1.0, 0.5]], rtol=0, atol=1e-15)
    assert robot[:2].tolist() == [2, 0]
    ref[0, 2] = [4.0, 3.69]  # beyond the gate: unmatched
    track_kernel.match(est, starts, ref, carriers, 0.3, 0.12, fused, robot, status)
    assert robot[:2].tolist() == [-1, 0] and status[0] == 0
    carriers[0, 0] = False  # not a carrier: never matched
    track_kernel.match(est, starts, ref, carriers, 0.3, 0.12, fused, robot, status)
    assert robot[:2].tolist() == [-1, -1]


def test_track_all_is_each_systems_track_on_random_worlds():
    """The compiled fusion and matching of B worlds (or the tracker where a world leaves the common
    case: fused clusters, crowded gates, promoted robots at their hand-over poses) gives each system's
    ``track``: the same fixes, tracker state and hand-over."""
    from parcover_env.localization.kinect import batch_update, track_kernel
    from parcover_env.localization.kinect.pipeline import PoseEstimate

    systems, _ = _systems([8, 9, 10])
    gate, fuse_radius = systems[0].tracking.gate, systems[0].tracking.fuse_radius  # 1 m, 0.12 m
    g = np.random.default_rng(5)
    n, flagged, kernel_fixed, handed = 6, 0, 0, 0
    for step in range(150):
        alone = [copy.deepcopy(s) for s in systems]
        markers = g.random((3, n)) < 0.5
        markers[:, 0] = True
        predicted = np.column_stack([g.uniform(0, 9, (3 * n, 2)), g.uniform(-3, 3, 3 * n)]).reshape(3, n, 3)
        world, pose = [], []
        for b in range(3):
            for i in np.flatnonzero(markers[b]):
                for _ in range(g.integers(0, 3)):  # 0, 1 or 2 Kinects see it
                    world.append(b)
                    pose.append(tuple(predicted[b, i] + g.normal(0, [0.5, 0.5, 0.5])))
        n_markers = int(g.integers(3, 6))
        found = batch_update.Detections(world, [0] * len(world), [0] * len(world), pose, n_markers)
        if step % 3 == 0:  # promoted robots (a carrier now or not) await their first detection
            promoted = {0: predicted[0, 0] + [0.8, 0.0, 0.0], 1: predicted[0, 1] + [0.0, -0.8, 0.0]}
            for s in [*systems, *alone]:
                s.hand_over(promoted, predicted[0])
        times = [0.1 * step] * 3
        got = batch_update.track_all(systems, found, markers, predicted, times)
        est = np.array([(*p, n_markers) for p in pose], dtype=float).reshape(-1, 4)
        starts = np.searchsorted(world, np.arange(4))
        status = np.empty(3, np.int64)
        track_kernel.match(est, starts, np.ascontiguousarray(predicted[..., :2]), markers, gate, fuse_radius,
                           np.empty((len(est), 3)), np.empty(len(est), np.int64), status)
        flagged += int(status.sum())
        for b, s in enumerate(alone):
            per = [PoseEstimate(*p, n_markers) for w, p in zip(world, pose, strict=True) if w == b]
            want = s.track([per], markers[b], predicted[b], times[b])
            assert list(got[b]) == list(want)
            for i in want:
                np.testing.assert_array_equal(got[b][i], want[i])
            kernel_fixed += len(want) if not status[b] else 0
            t, u = systems[b].tracker, s.tracker
            assert list(t.poses) == list(u.poses) and t.last_seen == u.last_seen
            for i in u.poses:
                np.testing.assert_array_equal(t.poses[i], u.poses[i])
            np.testing.assert_array_equal(np.reshape(t.unassigned, (-1, 3)), np.reshape(u.unassigned, (-1, 3)))
            assert systems[b].last_fixes.keys() == s.last_fixes.keys()
            assert systems[b].handover.keys() == s.handover.keys()
            # a promoted robot stays in the hand-over while it carries markers and is not detected
            assert set(systems[b].handover) <= set(np.flatnonzero(markers[b]).tolist()) - set(got[b])
            handed += len(systems[b].handover)
    assert 50 < flagged < 400 and kernel_fixed > 100, (flagged, kernel_fixed)  # both paths taken
    assert handed > 10


def test_update_systems_names_non_finite_poses_and_schedules_by_value():
    from parcover_env.localization.kinect.batch_kernels import schedule

    systems, _ = _systems([6, 7])
    poses = np.array([[[3.0, 4.0, 0.1], [5.0, 9.0, 1.0]], [[3.2, 4.1, 0.2], [np.nan, 9.0, 0.0]]])
    markers = np.array([[True, False], [True, True]])
    rngs = [np.random.default_rng(0), np.random.default_rng(1)]
    with pytest.raises(ValueError, match="poses contain NaN or inf"):
        update_systems(systems, [0.1, 0.1], poses, markers, poses, rngs)
    # the schedule by value: Kinect q due when its tick is within 1e-9 s of the clock, then one period on
    ticks = np.array([[0.1 + 5e-10, 0.1 + 2e-9, 0.0], [0.5, 0.3, 0.3]])
    due, active = np.empty((2, 3), bool), np.empty(2, bool)
    finite = schedule(ticks, np.array([0.1, 0.3]), np.array([0.25, 0.5, 1.0]), np.array([[True], [False]]),
                      np.zeros((2, 1, 3)), due, active)
    assert finite and due.tolist() == [[True, False, True], [False, True, True]]
    assert active.tolist() == [True, False]  # world 1 carries no markers
    np.testing.assert_allclose(ticks, [[0.35, 0.1 + 2e-9, 1.1], [0.5, 0.8, 1.3]], rtol=0, atol=1e-15)
    assert not schedule(ticks, np.zeros(2), np.ones(3), np.ones((2, 1), bool), np.full((2, 1, 3), np.inf), due,
                        active)


def test_track_rows_writes_the_world_starts_and_match_into_oversized_scratch():
    """Worlds 0 and 2 without detections, world 1 with two, world 3 with one: ``starts`` is where each
    world's rows begin (``searchsorted``'s left side), the rows beyond ``E`` and worlds beyond ``B`` of
    the scratch stay untouched, and the outputs are :func:`match`'s of the same estimates."""
    from parcover_env.localization.kinect import track_kernel

    world = np.array([1, 1, 3])
    pose = np.array([[1.0, 1.0, 0.2], [3.0, 1.0, -0.4], [7.0, 7.0, 1.0]])
    ref = np.zeros((4, 2, 3))
    ref[1] = [[3.1, 1.0, 0.0], [1.0, 1.2, 0.0]]
    ref[3] = [[9.0, 9.0, 0.0], [7.0, 7.1, 0.0]]
    carriers = np.ones((4, 2), bool)
    out = track_kernel.track_scratch(6, 5)
    for a in out:
        a.fill(-7)
    track_kernel.track_rows(world, pose, 4.0, ref, carriers, 0.3, 0.12, *out)
    assert out.starts.tolist() == [0, 0, 2, 2, 3, -7]
    assert out.status.tolist() == [0, 0, 0, 0, -7]
    assert out.robot.tolist() == [1, 0, 1, -7, -7, -7]
    np.testing.assert_array_equal(out.est[:3], np.column_stack([pose, np.full(3, 4.0)]))
    assert (out.est[3:] == -7).all() and (out.fused[3:] == -7).all()
    fused, robot, status = np.empty((3, 3)), np.empty(3, np.int64), np.empty(4, np.int64)
    track_kernel.match(out.est[:3], np.array([0, 0, 2, 2, 3]), ref, carriers, 0.3, 0.12, fused, robot, status)
    np.testing.assert_array_equal(out.fused[:3], fused)
    assert out.robot[:3].tolist() == robot.tolist()


def test_due_candidates_into_reused_scratch_equal_fresh_scratch():
    """The candidate rows of the due Kinects written into scratch that held a larger step before are
    those of fresh scratch: the due rows' (Kinect row, world, Kinect) in world-major order, the drop
    rates and the candidates (Kinect 1 of world 0, Kinects 0 and 2 of world 1 due)."""
    from parcover_env.localization.kinect import batch_kernels

    systems, bounds = _systems([6, 7])
    model = systems[0].fast
    s = len(model.sensors)
    assert s == 4
    kinects = np.concatenate([model.kinects.view(np.uint8)] * 2).view(estimate_kernel.KINECT)
    pattern = np.concatenate([model.pattern] * 2)
    g = np.random.default_rng(3)
    (x0, y0), (x1, y1) = bounds[:2], bounds[2:]
    poses = np.column_stack([g.uniform(x0, x1, 40), g.uniform(y0, y1, 40), g.uniform(-3, 3, 40)]).reshape(2, 20, 3)
    args = (poses, np.ones((2, 20), bool), kinects, pattern, model.depths, model.noise)
    reused = batch_kernels.candidate_rows(2 * s, 2 * s * 20)
    assert batch_kernels.due_candidates(np.ones((2, s), bool), *args, *reused)[1] > 0  # a larger step first
    due = np.zeros((2, s), bool)
    due[0, 1] = due[1, 0] = due[1, 2] = True
    fresh = batch_kernels.candidate_rows(2 * s, 2 * s * 20)
    r, n = batch_kernels.due_candidates(due, *args, *fresh)
    assert batch_kernels.due_candidates(due, *args, *reused) == (r, n) and r == 3 and n > 0
    assert reused.index[:9].reshape(3, 3).tolist() == [[1, s, s + 2], [0, 1, 1], [1, 0, 2]]
    np.testing.assert_array_equal(reused.index[:9], fresh.index[:9])
    np.testing.assert_array_equal(reused.drop[:3], fresh.drop[:3])
    for a, b in zip(reused[2:], fresh[2:], strict=True):
        np.testing.assert_array_equal(a[:n], b[:n])
    assert set(reused.row[:n].tolist()) <= {0, 1, 2} and (np.diff(reused.row[:n]) >= 0).all()
