"""Follower camera: lines of sight over batched worlds."""

from __future__ import annotations

import numpy as np

from parcover_env.sensors.relative import RelativeCamera, lines_of_sight_blocked


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


def test_precomputed_lines_of_sight_give_the_same_reading_and_draws():
    rng = np.random.default_rng(0)
    walls = np.array([[1.0, -1.0, 1.0, 1.0], [3.0, 0.0, 4.0, 2.0]])
    poses = np.concatenate([rng.uniform(0, 4, (6, 2)), rng.uniform(-3, 3, (6, 1))], axis=1)
    pred = np.array([-1, 0, 1, 2, 3, 4])
    cam = RelativeCamera(fov_deg=360.0, max_range=10.0)
    a = cam.measure(poses, pred, walls, np.random.default_rng(1))
    blocked = lines_of_sight_blocked(poses[None], pred[None], walls)[0]
    assert 0 < blocked.sum() < 5
    b = cam.measure(poses, pred, walls, np.random.default_rng(1), blocked)
    assert np.array_equal(a.visible, b.visible) and np.array_equal(a.rel_xy, b.rel_xy)
    assert np.array_equal(a.visible[1:], ~blocked[1:])
    c = cam.measure(poses, pred, walls, np.random.default_rng(1), np.zeros(6, bool))  # a lie: all clear
    assert c.visible[1:].all()
