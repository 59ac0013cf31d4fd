"""Follower camera: the noise figures come from ``FormationConfig`` and have the configured spread."""

from __future__ import annotations

import numpy as np
import pytest
from references import onboard as reference

import parcover_env
from parcover_env.config import ConfigError
from parcover_env.sensors.relative import RelativeCamera

NO_WALLS = np.zeros((0, 4))


def test_noise_free_camera_measures_the_robot_ahead_exactly():
    poses = np.array([[0.0, 0.0, np.pi / 2], [0.0, 1.0, np.pi]])  # robot 1 is 1 m straight ahead of 0
    cam = RelativeCamera(120.0, 2.5, 0.0, 0.0, 0.0)
    r = cam.measure(poses, np.array([1, -1]), NO_WALLS, np.random.default_rng(0))
    np.testing.assert_allclose(r.rel_xy[0], [1.0, 0.0], atol=1e-12)
    assert r.rel_heading[0] == pytest.approx(np.pi / 2) and r.visible.tolist() == [True, False]


def test_noise_has_the_configured_sigmas():
    n = 4000
    poses = np.zeros((2 * n, 3))
    poses[n:, 0] = 2.0  # follower i at the origin facing +x, its predecessor n + i 2 m ahead
    pred = np.r_[np.arange(n, 2 * n), -np.ones(n, int)]
    cam = RelativeCamera(120.0, 2.5, range_noise=0.02, bearing_noise=0.05, heading_noise=0.1)
    r = cam.measure(poses, pred, NO_WALLS, np.random.default_rng(1))
    rng_err = np.hypot(*r.rel_xy[:n].T) - 2.0
    bearing = np.arctan2(r.rel_xy[:n, 1], r.rel_xy[:n, 0])
    assert rng_err.std() == pytest.approx(0.02 * 2.0, rel=0.05)  # per metre of distance
    assert bearing.std() == pytest.approx(0.05, rel=0.05) and r.rel_heading[:n].std() == pytest.approx(0.1, rel=0.05)


def test_env_builds_the_camera_from_the_formation_config():
    env = parcover_env.parallel_env("office", overrides={"formation": {"camera_bearing_noise": 0.2,
                                                                         "camera_range_noise": 0.0}})
    assert (env.camera.bearing_noise, env.camera.range_noise, env.camera.heading_noise) == (0.2, 0.0, 0.03)


@pytest.mark.parametrize("key", ["camera_range_noise", "camera_bearing_noise", "camera_heading_noise"])
def test_negative_camera_noise_names_the_key(key):
    with pytest.raises(ConfigError, match=key):
        parcover_env.parallel_env("office", overrides={"formation": {key: -0.01}})


def test_each_noise_term_enters_with_its_sign_and_scale():
    poses = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.5]])
    cam = RelativeCamera(120.0, 2.5, range_noise=0.1, bearing_noise=0.05, heading_noise=0.2)
    seed = next(s for s in range(100) if (np.random.default_rng(s).standard_normal(3) > 0.5).all())
    z1, z2, z3 = np.random.default_rng(seed).standard_normal(3)  # range, bearing, heading: all positive
    r = cam.measure(poses, np.array([1, -1]), NO_WALLS, np.random.default_rng(seed))
    dist = 2.0 * (1.0 + 0.1 * z1)  # sigma per metre, relative to the true range
    np.testing.assert_allclose(r.rel_xy[0], [dist * np.cos(0.05 * z2), dist * np.sin(0.05 * z2)], atol=1e-12)
    assert r.rel_heading[0] == pytest.approx(0.5 + 0.2 * z3)


@pytest.mark.parametrize("ahead, walls, seen", [
    ((2.4, 0.0), NO_WALLS, True),                                     # in range
    ((2.5, 0.0), NO_WALLS, True),                                     # at max_range: still seen
    ((2.6, 0.0), NO_WALLS, False),                                    # beyond max_range
    ((np.cos(np.radians(59)), np.sin(np.radians(59))), NO_WALLS, True),   # inside the 120 deg field of view
    ((np.cos(np.radians(61)), np.sin(np.radians(61))), NO_WALLS, False),  # just outside it
    ((1.0, 0.0), np.array([[0.5, -1.0, 0.5, 1.0]]), False),           # a wall in between
    ((1.0, 0.0), np.array([[1.5, -1.0, 1.5, 1.0]]), True),            # a wall behind the robot ahead
])
def test_visibility_needs_range_field_of_view_and_line_of_sight(ahead, walls, seen):
    poses = np.array([[0.0, 0.0, 0.0], [ahead[0], ahead[1], 0.3]])
    r = RelativeCamera(120.0, 2.5, 0.0, 0.0, 0.0).measure(poses, np.array([1, -1]), walls,
                                                        np.random.default_rng(0))
    assert r.visible.dtype == bool and r.visible.tolist() == [seen, False]
    if seen:
        np.testing.assert_allclose(r.rel_xy[0], ahead, atol=1e-12)
        assert r.rel_heading[0] == pytest.approx(0.3)
    else:  # an unseen robot reads all zeros
        assert r.rel_xy[0].tolist() == [0.0, 0.0] and r.rel_heading[0] == 0.0


def test_without_followers_the_reading_is_zeros_of_the_right_shape():
    r = RelativeCamera().measure(np.zeros((3, 3)), -np.ones(3, int), NO_WALLS, np.random.default_rng(0))
    assert r.rel_xy.shape == (3, 2) and r.rel_heading.shape == (3,) and r.visible.dtype == bool
    assert not r.rel_xy.any() and not r.rel_heading.any() and not r.visible.any()


def test_compiled_camera_equals_the_numpy_formulas_bit_for_bit():
    cam = RelativeCamera(fov_deg=300.0, max_range=1.0, range_noise=0.05, bearing_noise=0.04, heading_noise=0.1)
    draw = np.random.default_rng(3)
    poses = np.concatenate([draw.uniform(0, 1.2, (40, 2)), draw.uniform(-4, 4, (40, 1))], axis=1)
    predecessor = np.where(draw.random(40) < 0.8, draw.integers(0, 40, 40), -1)
    walls = np.array([[0.6, 0.0, 0.6, 0.6]])
    a, b = np.random.default_rng(6), np.random.default_rng(6)
    got = cam.measure(poses, predecessor, walls, a)
    want = reference.camera_view(cam, poses, predecessor, walls, b)
    assert 5 < got.visible.sum() < 30  # some seen, some not
    for g, w in zip((got.rel_xy, got.rel_heading, got.visible), want, strict=True):
        assert np.array_equal(g, w)
    assert a.random() == b.random()  # the same number of draws
