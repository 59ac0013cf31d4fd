"""The 2-D lidar on hand-built situations: wall distances, robots in the beam, noise, max range."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config.robot import LidarConfig
from parcover_env.errors import ConfigError
from parcover_env.sensors.base import SensingState, Sensor
from parcover_env.sensors.lidar import Lidar

WALL = np.array([[3.0, -5.0, 3.0, 5.0]])  # a vertical wall at x = 3


def _state(poses, segments=WALL, radius=0.15, worlds=None):
    poses = np.asarray(poses, dtype=float)
    poses = poses[None] if poses.ndim == 2 else poses
    return SensingState(poses, np.asarray(segments, dtype=float).reshape(-1, 4), radius,
                        np.full(poses.shape[:2], -1, dtype=np.int64))


def test_a_robot_reads_its_distance_to_a_wall_and_max_range_elsewhere():
    lidar = Lidar(LidarConfig(enabled=True, n_rays=4, range_max=5.0, noise_std=0.0))
    assert isinstance(lidar, Sensor) and lidar.size == 4
    got = lidar.sense(_state([[1.0, 1.0, 0.0]]), [np.random.default_rng(0)])
    assert got.shape == (1, 1, 4) and got.dtype == np.float32
    assert got[0, 0].tolist() == [2.0, 5.0, 5.0, 5.0]  # ahead: 2 m to the wall; left, behind, right: nothing
    turned = lidar.sense(_state([[1.0, 1.0, math.pi / 2]]), [np.random.default_rng(0)])  # facing +y
    assert turned[0, 0].tolist() == pytest.approx([5.0, 5.0, 5.0, 2.0])  # the wall is now on the right (ray 3)


def test_beyond_range_reads_max_range():
    lidar = Lidar(LidarConfig(enabled=True, n_rays=4, range_max=1.5, noise_std=0.2))
    got = lidar.sense(_state([[1.0, 1.0, 0.0]]), [np.random.default_rng(3)])
    assert got[0, 0].tolist() == [1.5, 1.5, 1.5, 1.5]  # the wall 2 m away is out of range: exactly range_max


def test_another_robot_in_the_beam_and_the_own_disc_ignored():
    lidar = Lidar(LidarConfig(enabled=True, n_rays=4, range_max=5.0, noise_std=0.0))
    poses = [[0.0, 0.0, 0.0], [1.2, 0.0, math.pi]]  # facing each other, 1.2 m apart, wall at x = 3
    got = lidar.sense(_state(poses, radius=0.2), [np.random.default_rng(0)])[0]
    assert got[0, 0] == pytest.approx(1.0)  # robot 0 ahead: robot 1's disc at 1.2 - 0.2
    assert got[1, 0] == pytest.approx(1.0)  # robot 1 ahead (towards -x): robot 0's disc
    assert got[1, 2] == pytest.approx(1.8)  # robot 1 behind: the wall at x = 3, not its own disc
    off_axis = lidar.sense(_state([[0.0, 0.0, 0.0], [1.2, 0.1, 0.0]], radius=0.2), [np.random.default_rng(0)])[0]
    assert off_axis[0, 0] == pytest.approx(1.2 - math.sqrt(0.2**2 - 0.1**2))  # chord of a disc 0.1 m off the ray


def test_worlds_see_only_their_own_robots():
    lidar = Lidar(LidarConfig(enabled=True, n_rays=4, range_max=5.0, noise_std=0.0))
    poses = np.array([[[0.0, 0.0, 0.0], [1.2, 0.0, 0.0]], [[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]]])
    got = lidar.sense(_state(poses, radius=0.2), [np.random.default_rng(0)] * 2)
    assert got[0, 0, 0] == pytest.approx(1.0) and got[1, 0, 0] == pytest.approx(3.0)  # world 1: the wall


def test_noise_is_gaussian_with_the_configured_sigma_and_per_world_generators():
    sigma, k = 0.05, 400
    lidar = Lidar(LidarConfig(enabled=True, n_rays=4, range_max=5.0, noise_std=sigma))
    poses = np.tile([[[1.0, 1.0, 0.0]]], (k, 1, 1))
    rngs = [np.random.default_rng(100 + i) for i in range(k)]
    ray0 = lidar.sense(_state(poses), rngs)[:, 0, 0].astype(float)
    err = ray0 - 2.0
    assert abs(err.mean()) < 4 * sigma / math.sqrt(k)
    assert err.std() == pytest.approx(sigma, rel=0.12)
    one = lidar.sense(_state(poses[5]), [np.random.default_rng(105)])  # world 5 alone, same generator
    assert one[0, 0, 0] == np.float32(ray0[5])


def test_a_negative_noisy_range_is_clipped_to_zero():
    lidar = Lidar(LidarConfig(enabled=True, n_rays=1, range_max=5.0, noise_std=1.0))
    got = lidar.sense(_state(np.tile([[[2.999, 0.0, 0.0]]], (200, 1, 1))),
                      [np.random.default_rng(i) for i in range(200)])
    assert got.min() == 0.0 and got.max() <= 5.0


def test_bad_config_is_one_clear_error():
    with pytest.raises(ConfigError, match="n_rays"):
        LidarConfig(n_rays=0)
    with pytest.raises(ConfigError, match="noise_std"):
        LidarConfig(noise_std=-0.1)
