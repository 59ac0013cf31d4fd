"""The grid fallback's scan errors with an exact early exit (``grid_kernels``): the error floor by value, and
on hand-built rooms every pose's error bit for bit or skipped only when it could not have won."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import SonarConfig
from parcover_env.localization.sonar import grid_kernels
from parcover_env.localization.sonar.localizer import _bounded_errors, scan_error, synthetic_scans
from parcover_env.localization.sonar.params import SonarLocalizerParams
from parcover_env.sensors.sonar import SonarRing, simulate_beams

ROOM = np.array([[0.0, 0.0, 4.0, 0.0], [4.0, 0.0, 4.0, 3.0], [4.0, 3.0, 2.5, 3.0], [2.5, 3.0, 2.5, 2.0],
                 [2.5, 2.0, 0.0, 2.0], [0.0, 2.0, 0.0, 0.0], [1.0, 0.8, 1.6, 1.3]])
"""An L-shaped room (walls counter-clockwise) with an oblique free wall inside: corners, mirrors, shadows."""


def test_error_floor_is_the_sum_of_the_smallest_distances_to_the_intervals():
    """Measured 1.0 below [1.2, 1.5] (0.2), 2.0 above [1.0, 1.5] (0.5, clipped to 0.3), 0.5 inside [0, 3]
    (0), 2.6 beyond range_max 2.54 with an interval [2.0, inf] read as [2.0, 2.54] (0.06): the two
    smallest sum to 0.06; as points at the high ends, 0.3 + 0.3 + 0.3 + 0.06."""
    measured = np.array([1.0, 2.0, 0.5, 2.6])
    low = np.array([1.2, 1.0, 0.0, 2.0])
    high = np.array([1.5, 1.5, 3.0, np.inf])
    buf = np.empty(4)
    assert grid_kernels.error_floor(measured, low, high, 2.54, 0.3, 2, buf) == pytest.approx(0.06, abs=1e-12)
    assert grid_kernels.error_floor(measured, low, high, 2.54, 0.3, 4, buf) == pytest.approx(0.56, abs=1e-12)
    assert grid_kernels.error_floor(measured, high, high, 2.54, 0.3, 4, buf) == pytest.approx(0.96)


@pytest.mark.parametrize("best", [math.inf, 0.05, 0.0])
@pytest.mark.parametrize("centre", [None, (1.9, 1.1, 0.4)])
def test_skipped_poses_could_not_have_won_and_the_others_are_bit_identical(best, centre):
    """A 9 x 9 x 5 grid of poses in the room, scan measured from one of them (realistic sonar noise): each
    pose's error is that of its synthetic scan bit for bit, or inf only if that error exceeds the smallest
    tried before it (``best`` first; in index order, or nearest ``centre`` first) by the slack; the first
    smallest error of ``[best, errors]`` is the same."""
    cfg = SonarConfig()
    ring = SonarRing(cfg)
    p = SonarLocalizerParams()
    segs = np.ascontiguousarray(ROOM)
    truth = np.array([1.9, 1.1, 0.4])
    measured = ring.scan(truth, segs, None, 0.17, np.random.default_rng(4))
    xs, ys, hs = np.meshgrid(np.linspace(1.5, 2.3, 9), np.linspace(0.7, 1.5, 9), 0.4 + np.radians([-8, -4, 0, 4, 8]))
    poses = np.column_stack([xs.ravel(), ys.ravel(), hs.ravel()])
    full = scan_error(measured, synthetic_scans(poses, ring.scan_angles, segs, cfg), p.error_clip, p.error_trim)
    got = _bounded_errors(measured, poses, ring.scan_angles, segs, cfg, p, best, centre)
    done = np.isfinite(got)
    assert got[done].tobytes() == full[done].tobytes()
    order = np.arange(len(poses))
    if centre is not None:  # nearest the centre first, spot by spot, the centre's heading first
        order = np.lexsort((np.abs(poses[:, 2] - 0.4), np.arange(len(poses)) // 5,
                            np.hypot(poses[:, 0] - 1.9, poses[:, 1] - 1.1)))
        assert order[0] == 4 * 45 + 4 * 5 + 2  # the grid's middle spot (1.9, 1.1), heading 0.4
    so_far = np.empty(len(poses))
    so_far[order] = np.minimum.accumulate(np.concatenate([[best], full[order]]))[:-1]  # smallest tried before
    assert (full[~done] > so_far[~done] * (1 + grid_kernels.BOUND_SLACK)).all()
    assert np.argmin(np.concatenate([[best], got])) == np.argmin(np.concatenate([[best], full]))
    if best > 0:
        assert 0.2 * len(poses) < (~done).sum() <= len(poses) - 1  # the bound bites, and the winner stays
    else:
        assert (~done).sum() == len(poses)  # nothing beats an error of 0


def test_robots_among_the_walls_read_as_the_sonar_reads_them():
    """With discs (robots) in the scene the kernel's readings are the sonar's: poses whose error it computes
    match simulate_beams' scans bit for bit."""
    from parcover_env.geometry.rays import disc_planes
    from parcover_env.sensors.sonar import beam_kernel_arguments
    from parcover_env.sensors.sonar_kernels import Discs

    cfg = SonarConfig()
    ring = SonarRing(cfg)
    segs = np.ascontiguousarray(ROOM)
    robots = np.array([[2.2, 0.5], [3.3, 1.6]])
    rng = np.random.default_rng(2)
    poses = np.column_stack([rng.uniform(1.2, 3.6, 30), rng.uniform(0.4, 1.7, 30), rng.uniform(-3, 3, 30)])
    axes = np.ascontiguousarray(poses[:, 2:3] + ring.scan_angles[None, :])
    want = simulate_beams(cfg, poses[:, :2], axes, segs, robots, 0.17, np.full(30, -1))
    measured = want[15].copy()
    walls, offsets, share, rules = beam_kernel_arguments(cfg, segs, axes)
    out = np.empty(30)
    grid_kernels.bounded_scan_errors(np.ascontiguousarray(poses[:, 0]), np.ascontiguousarray(poses[:, 1]), axes,
                                     offsets, share, walls, Discs(*disc_planes(robots, 0.17, np.full(30, -1), 30)),
                                     rules, grid_kernels.ScanTarget(measured, 0.5, 65, math.inf), out)
    full = scan_error(measured, want, 0.5, 0.1)
    done = np.isfinite(out)
    assert out[done].tobytes() == full[done].tobytes() and done[:16].sum() >= 3
    assert out[15] == 0.0 and np.isinf(out[16:]).all() and (full[16:] > 0).all()  # nothing after beats 0


def test_pose_readings_equal_beam_readings():
    """The polish's one-pose cast into its scratch reads what beam_readings reads, pose after pose, robots
    among the walls."""
    from parcover_env.geometry.rays import disc_planes
    from parcover_env.sensors import sonar_kernels as kern
    from parcover_env.sensors.sonar import beam_kernel_arguments

    cfg = SonarConfig()
    ring = SonarRing(cfg)
    segs = np.ascontiguousarray(ROOM)
    rng = np.random.default_rng(6)
    poses = np.column_stack([rng.uniform(0.3, 3.7, 12), rng.uniform(0.3, 1.8, 12), rng.uniform(-3, 3, 12)])
    axes = np.ascontiguousarray(poses[:, 2:3] + ring.scan_angles[None, :])
    walls, offsets, share, rules = beam_kernel_arguments(cfg, segs, axes)
    discs = kern.Discs(*disc_planes(np.array([[2.2, 0.5], [3.3, 1.6]]), 0.17, np.full(1, -1), 1))
    ps = kern.pose_scratch(offsets, share, walls, 2)
    for k in range(12):
        want = np.empty((1, 72))
        kern.beam_readings(poses[k:k + 1, 0].copy(), poses[k:k + 1, 1].copy(), axes[k:k + 1], offsets, share, walls,
                           discs, rules, want)
        got = np.empty(72)
        kern.pose_readings(poses[k, 0], poses[k, 1], axes[k], share, walls, discs, rules, got, ps)
        assert got.tobytes() == want[0].tobytes(), k
        assert (got < cfg.range_max).sum() > 30
