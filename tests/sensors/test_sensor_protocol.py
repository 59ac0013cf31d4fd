"""The Sensor protocol: the observation sensors' ``sense`` over (worlds x robots) equals their
per-world ``measure`` drawn from each world's own generator."""

from __future__ import annotations

import numpy as np
import pytest

from parcover_env.config import SonarConfig
from parcover_env.sensors.base import SensingState, Sensor
from parcover_env.sensors.relative import RelativeCamera
from parcover_env.sensors.sonar import SonarRing

ROOM = np.array([[0, 0, 6, 0], [6, 0, 6, 4], [6, 4, 0, 4], [0, 4, 0, 0]], dtype=float)


def _worlds(k=3, n=3, seed=0):
    g = np.random.default_rng(seed)
    poses = np.concatenate([g.uniform(0.5, 3.5, (k, n, 2)), g.uniform(-3, 3, (k, n, 1))], axis=2)
    poses[..., 0] = np.linspace(0.8, 2.6, n)  # a column: followers behind, in sight
    predecessor = np.tile(np.arange(-1, n - 1), (k, 1))
    return SensingState(poses, ROOM, 0.15, predecessor)


@pytest.mark.parametrize("cfg", [{}, {"garbage_rate": 0.2}, {"model": "fast"},
                                 {"model": "fast", "dropout_prob": 0.3, "garbage_rate": 0.2}])
def test_sonar_sense_is_each_worlds_measure(cfg):
    ring = SonarRing(SonarConfig(**cfg))  # every kind of draw: cross-talk, noise, dropouts, garbage
    state = _worlds()
    assert isinstance(ring, Sensor) and ring.size == 16
    got = ring.sense(state, [np.random.default_rng(10 + k) for k in range(3)])
    assert got.shape == (3, 3, 16)
    for k in range(3):
        alone = ring.measure(state.poses[k], ROOM, 0.15, np.random.default_rng(10 + k))
        assert np.array_equal(got[k], alone)
    assert not np.array_equal(got[0], got[1])


def test_camera_sense_is_each_worlds_measure():
    cam = RelativeCamera(fov_deg=360.0, max_range=5.0)
    state = _worlds()
    assert isinstance(cam, Sensor) and cam.size == 4
    got = cam.sense(state, [np.random.default_rng(20 + k) for k in range(3)])
    for k in range(3):
        r = cam.measure(state.poses[k], state.predecessor[k], ROOM, np.random.default_rng(20 + k))
        back = RelativeCamera.reading(got[k])
        assert np.array_equal(back.rel_xy, r.rel_xy) and np.array_equal(back.rel_heading, r.rel_heading)
        assert np.array_equal(back.visible, r.visible)
    assert got[:, 1:, 3].all() and not got[:, 0, 3].any()  # followers see their predecessor, the leader none
