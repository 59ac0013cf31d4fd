"""Follower camera: lines of sight over batched worlds."""

from __future__ import annotations

import math

import numpy as np

from parcover_env.sensors.relative import RelativeCamera, lines_of_sight_blocked

NO_WALLS = np.zeros((0, 4))


def test_lines_of_sight_blocked_per_world_by_hand():
    wall = np.array([[1.0, -1.0, 1.0, 1.0]])  # x = 1, from y = -1 to 1
    poses = np.array([
        [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.0]],  # world 0: 1 -> 0 crosses the wall
        [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [2.0, 4.0, 0.0]],  # world 1: 1 -> 0 does not; 2 -> 1 passes above
    ])
    pred = np.array([[-1, 0, 0], [-1, 0, 1]])
    got = lines_of_sight_blocked(poses, pred, wall)
    assert got.tolist() == [[False, True, False], [False, False, False]]
    swapped = lines_of_sight_blocked(poses[::-1], pred[::-1], wall)  # the same worlds, in the other order
    assert swapped.tolist() == [[False, False, False], [False, True, False]]


def _expected(cam, poses, pred, seen, rng):
    """The camera's reading of one world by its formula, from ``rng``'s normals (one triple per follower)."""
    z = rng.standard_normal((3, int((pred >= 0).sum())))
    rel_xy, heading = np.zeros((len(poses), 2)), np.zeros(len(poses))
    for f, i in enumerate(np.flatnonzero(pred >= 0)):
        j = pred[i]
        d = poses[j, :2] - poses[i, :2]
        if seen[i]:
            r = np.hypot(*d) * (1 + cam.range_noise * z[0, f])
            b = math.atan2(d[1], d[0]) - poses[i, 2] + cam.bearing_noise * z[1, f]
            rel_xy[i] = r * math.cos(b), r * math.sin(b)
            heading[i] = math.remainder(poses[j, 2] - poses[i, 2] + cam.heading_noise * z[2, f], 2 * math.pi)
    return rel_xy, heading


def test_measure_many_of_two_worlds_by_value_each_world_its_own_draws():
    walls = np.array([[3.0, 0.0, 3.0, 2.5]])  # x = 3, from y = 0 to 2.5
    poses = np.array([
        [[1.0, 1.0, 0.0], [2.0, 1.0, math.pi], [4.0, 1.0, math.pi]],  # 1 sees 0; 2 -> 1 crosses the wall
        [[1.0, 1.5, 0.0], [5.0, 3.0, 0.0], [1.0, 3.0, -math.pi / 2]],  # 1 leads; 2 sees 0, 1.5 m below it
    ])
    pred = np.array([[-1, 0, 1], [-1, -1, 0]])
    cam = RelativeCamera(fov_deg=120.0, max_range=2.5, range_noise=0.05, bearing_noise=0.1, heading_noise=0.2)
    got = cam.measure_many(poses, pred, walls, [np.random.default_rng(1), np.random.default_rng(2)])
    assert got.visible.tolist() == [[False, True, False], [False, False, True]]
    for k, seed in enumerate((1, 2)):
        rel_xy, heading = _expected(cam, poses[k], pred[k], got.visible[k], np.random.default_rng(seed))
        np.testing.assert_allclose(got.rel_xy[k], rel_xy, atol=1e-12)
        np.testing.assert_allclose(got.rel_heading[k], heading, atol=1e-12)
        alone = cam.measure(poses[k], pred[k], walls, np.random.default_rng(seed))
        assert all(np.array_equal(a, b[k]) for a, b in zip(alone, got, strict=True))  # bit for bit
    assert abs(got.rel_xy[1, 2, 0] - 1.5) < 0.5 and abs(got.rel_xy[0, 1, 0] - 1.0) < 0.5  # its own world's robot


def test_a_world_without_followers_draws_nothing_and_the_others_read_as_alone():
    poses = np.array([
        [[1.0, 1.0, 0.0], [2.0, 1.0, math.pi], [0.0, 0.0, 0.0]],  # 1 sees 0, 1 m ahead
        [[1.0, 1.0, 0.0], [2.0, 1.0, math.pi], [0.0, 0.0, 0.0]],  # the same robots, nobody follows
        [[0.0, 0.0, 0.0], [0.0, 2.0, 0.0], [1.0, 0.0, math.pi]],  # 2 sees 0, 1 m ahead
    ])
    pred = np.array([[-1, 0, -1], [-1, -1, -1], [-1, -1, 0]])
    cam = RelativeCamera(fov_deg=120.0, max_range=2.5, range_noise=0.05, bearing_noise=0.1, heading_noise=0.2)
    rngs = [np.random.default_rng(s) for s in (1, 2, 3)]
    got = cam.measure_many(poses, pred, NO_WALLS, rngs)
    assert rngs[1].bit_generator.state == np.random.default_rng(2).bit_generator.state  # untouched
    assert rngs[1].random() == np.random.default_rng(2).random()
    assert got.visible.tolist() == [[False, True, False], [False, False, False], [False, False, True]]
    assert not got.rel_xy[1].any() and not got.rel_heading[1].any()
    for k in (0, 2):
        alone = cam.measure(poses[k], pred[k], NO_WALLS, np.random.default_rng(k + 1))
        assert all(np.array_equal(a, b[k]) for a, b in zip(alone, got, strict=True))  # bit for bit
    z = np.random.default_rng(3).standard_normal(3)  # world 2's one follower: range, bearing, heading
    r, b = 1.0 + 0.05 * z[0], 0.1 * z[1]
    np.testing.assert_allclose(got.rel_xy[2, 2], [r * math.cos(b), r * math.sin(b)], atol=1e-12)
    np.testing.assert_allclose(got.rel_heading[2, 2], math.remainder(-math.pi + 0.2 * z[2], 2 * math.pi), atol=1e-12)
