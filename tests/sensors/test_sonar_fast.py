"""The ``fast`` sonar model: one ray per beam, noise and dropouts, none of the specular effects."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import SonarConfig
from parcover_env.errors import ConfigError
from parcover_env.sensors.sonar import SonarRing

OBLIQUE = np.array([[1.0, -1.0, 3.0, 1.0]])
"""A wall the +x axis from the origin meets at x = 2, 45 degrees off its normal."""
RADIUS = 0.1


def _ring(**kw) -> SonarRing:
    kw = {"n_beams": 4, "quantization": 0.0, "noise_std": 0.0, "noise_rel": 0.0} | kw
    return SonarRing(SonarConfig(**kw))


def test_oblique_wall_echoes_in_the_fast_model_only():
    pose = np.array([[0.0, 0.0, 0.0]])
    fast = _ring(model="fast").measure(pose, OBLIQUE, RADIUS, np.random.default_rng(0))
    spec = _ring(model="specular").measure(pose, OBLIQUE, RADIUS, np.random.default_rng(0))
    assert fast[0, 0] == pytest.approx(2.0, abs=1e-6)  # no incidence limit
    assert spec[0, 0] == pytest.approx(2.54)  # 45 deg > 20 deg: mirrored away, lost
    assert np.all(fast[0, 1:] == pytest.approx(2.54))  # the other beams see nothing


def test_robots_of_the_world_block_and_echo_and_never_cross_talk():
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, math.pi]])
    ring = _ring(model="fast", crosstalk_prob=1.0)
    got = ring.measure(poses, OBLIQUE, RADIUS, np.random.default_rng(0))
    assert got[0, 0] == pytest.approx(0.9, abs=1e-6)  # the other robot's disc, not the wall at 2 m
    assert got[1, 0] == pytest.approx(0.9, abs=1e-6)
    assert got[0, 2] == pytest.approx(2.54)  # facing away: cross-talk (d / 2 = 0.5) would read 0.5


def test_noise_and_dropouts_follow_the_draws_in_order():
    cfg = SonarConfig(model="fast", n_beams=4, noise_std=0.02, noise_rel=0.01, quantization=0.01, dropout_prob=0.5)
    ring = SonarRing(cfg)
    poses = np.array([[0.0, 0.0, 0.0], [0.0, 0.5, 0.0]])
    ideal = ring.measure(poses, OBLIQUE, RADIUS, None).astype(float)
    got = ring.measure(poses, OBLIQUE, RADIUS, np.random.default_rng(7))
    rng = np.random.default_rng(7)
    z, drop = rng.standard_normal(8).reshape(2, 4), rng.random(8).reshape(2, 4)
    echo = (ideal < 2.54) & (drop >= 0.5)
    noisy = np.rint((ideal + (0.02 + 0.01 * ideal) * z) / 0.01) * 0.01
    want = np.where(echo, np.clip(noisy, 0.15, 2.54), 2.54)
    np.testing.assert_allclose(got, want, atol=1e-6)
    assert 0 < echo.sum() < (ideal < 2.54).sum()  # this seed drops some echoes and keeps others
    assert ideal[0, 0] == pytest.approx(2.0, abs=1e-6) and ideal[1, 0] == pytest.approx(2.5, abs=1e-6)
    after = np.random.default_rng(7)
    ring.draw(2, after)  # the draws: noise normals, dropout uniforms, nothing else
    assert after.random() == rng.random()


def test_every_echo_is_lost_at_dropout_one_and_batched_worlds_match_alone():
    ring = _ring(model="fast", dropout_prob=1.0)
    assert np.all(ring.measure(np.zeros((1, 3)), OBLIQUE, RADIUS, np.random.default_rng(0)) == np.float32(2.54))
    ring = _ring(model="fast", noise_std=0.01, dropout_prob=0.2, n_beams=16)
    poses = np.array([[[0.0, 0.0, 0.3], [0.2, 0.6, 1.0]], [[0.5, 0.1, -2.0], [0.0, -0.7, 2.5]]])
    draws = [ring.draw(2, np.random.default_rng(s)) for s in (1, 2)]
    both = ring.readings(poses, OBLIQUE, RADIUS, draws)
    for k, s in enumerate((1, 2)):
        assert np.array_equal(both[k], ring.measure(poses[k], OBLIQUE, RADIUS, np.random.default_rng(s)))


def test_dropout_prob_is_checked():
    with pytest.raises(ConfigError, match="dropout_prob"):
        SonarConfig(model="fast", dropout_prob=1.5)


def test_scan_and_corrupt_use_the_fast_model():
    ring = _ring(model="fast", noise_std=0.01)
    scan = ring.scan(np.zeros(3), OBLIQUE, None, RADIUS, None)
    assert scan[0] == pytest.approx(2.0, abs=1e-9) and scan.shape == (72,)
    assert np.all(_ring(model="fast", dropout_prob=1.0).corrupt(scan, np.random.default_rng(0)) == 2.54)
    noisy = ring.corrupt(scan, np.random.default_rng(0))
    z = np.random.default_rng(0).standard_normal(72)
    assert noisy[0] == pytest.approx(2.0 + 0.01 * z[0])  # noise_rel 0 here


def test_noise_free_fast_readings_are_the_ideal_ray_bit_for_bit():
    from parcover_env.config import MapConfig
    from parcover_env.world.map_model import MapModel

    room = MapModel.from_config(MapConfig(size=(4.0, 4.0), obstacles=(((1.0, 1.0), (1.6, 1.2), (1.2, 1.8)),)))
    rng = np.random.default_rng(5)
    pts = rng.uniform(0, 4, (200, 2))
    pts = pts[room.contains(pts, margin=0.2)][:6]
    poses = np.column_stack([pts, rng.uniform(-math.pi, math.pi, len(pts))])
    poses = np.vstack([poses, [0.0, 2.0, 0.0], [4.0, 2.0, 0.0]])  # on the walls x = 0 and 4 (a reach box edge)
    fast = _ring(model="fast", n_beams=16, below_min="clip")
    ray = _ring(model="ray", n_beams=16, below_min="clip", crosstalk_prob=0.0)
    got = fast.measure(poses, room.segments, 0.165, np.random.default_rng(0))  # the compiled fast ring
    want = ray.measure(poses, room.segments, 0.165, None)
    assert np.array_equal(got, want)
    assert np.mean(got < 2.54) > 0.5  # mostly echoes: the room is 4 m wide


def test_robots_beyond_reach_are_skipped_without_changing_a_bit():
    from parcover_env.config import MapConfig
    from parcover_env.world.map_model import MapModel

    room = MapModel.from_config(MapConfig(size=(9.0, 9.0)))
    rng = np.random.default_rng(11)
    k, n, r = 3, 12, 0.165
    poses = np.column_stack([rng.uniform(0.5, 8.5, (k * n, 2)), rng.uniform(-math.pi, math.pi, k * n)]).reshape(k, n, 3)
    poses[0, 2:, 1] = rng.uniform(6.0, 8.5, n - 2)  # world 0: robots 2... away from robots 0 and 1
    poses[0, 0], poses[0, 1] = [1.0, 3.0, 0.0], [1.0 + 2.54 + r - 0.05, 3.0, 1.0]  # 1 is 2.49 m ahead of 0
    poses[1, 2, :2] = poses[1, 3, :2] + [0.2, 0.1]  # two discs overlapping
    fast = _ring(model="fast", n_beams=16, below_min="clip")
    ray = _ring(model="ray", n_beams=16, below_min="clip", crosstalk_prob=0.0)
    draws = [fast.draw(n, np.random.default_rng(w)) for w in range(k)]
    got = fast.readings(poses, room.segments, r, draws)
    for w in range(k):
        assert np.array_equal(got[w], ray.measure(poses[w], room.segments, r, None))
    assert got[0, 0, 0] == pytest.approx(2.49, abs=1e-6) and got[1, 2].min() == np.float32(0.15)  # inside: clipped
    assert np.mean(got < 2.54) > 0.1  # robots and walls echo


def _fan(n_rays: int, phase: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    a = phase + np.arange(n_rays) * (2 * math.pi / n_rays)
    return np.cos(a), np.sin(a)


def _segment_fan(x0, y0, dx, dy, segs, near, boxes, best):
    """:func:`~parcover_env.geometry.ray_kernels.segment_fan`'s nearest hits into ``best`` (what the
    fast ring reads)."""
    from parcover_env.geometry.ray_kernels import segment_fan

    n = dx.shape[0]
    segment_fan(x0, y0, dx, dy, segs, near, boxes, best, np.empty(n, np.int64), np.empty(n))


def test_segment_fan_hits_the_nearest_wall_of_each_ray_by_value():
    segment_fan = _segment_fan

    # a wall x = 2 (y in [-2.5, 1]), a nearer one x = 1 (y in [0.5, 1.5]), one along the -x axis
    segs = np.array([[2.0, -2.5, 2.0, 1.0], [1.0, 0.5, 1.0, 1.5], [-3.0, 0.0, -1.0, 0.0]])
    dx, dy = _fan(8)  # 0, 45, 90, ..., 315 degrees
    best = np.full(8, -1.0)
    segment_fan(0.0, 0.0, dx, dy, segs, np.arange(3), np.empty((0, 8)), best)
    assert best[0] == 2.0  # +x: the far wall; the near one is above the ray
    assert best[1] == pytest.approx(math.sqrt(2))  # 45 deg: the near wall at (1, 1), before the far one
    assert best[7] == pytest.approx(2 * math.sqrt(2))  # -45 deg: the far wall at (2, -2)
    assert np.isinf(best[2:7]).all()  # -x runs along the third wall (parallel): no hit; the others miss
    segment_fan(0.0, 0.0, dx, dy, segs, np.array([0, 2]), np.empty((0, 8)), best)
    assert np.isinf(best[1]) and best[0] == 2.0  # only the listed walls count: the near one is left out
    boxes = np.array([np.full(8, -1.0), np.full(8, 1.5), np.full(8, -1.0), np.full(8, 1.0)])
    segment_fan(0.0, 0.0, dx, dy, segs, np.arange(3), boxes, best)
    assert best[1] == pytest.approx(math.sqrt(2)) and np.isinf(best[0])  # the far wall lies outside every box
    segment_fan(0.0, 0.0, dx, dy, np.array([[-3.0, 0.0, 1.0, 0.0]]), np.arange(1), np.empty((0, 8)), best)
    assert best[2] == 0.0 and best[6] == 0.0  # starting on a wall: 0 across it
    assert np.isinf(best[0]) and np.isinf(best[4])  # along it (-x: |d x e| ~ 5e-16, not exactly 0): no hit
    ends = np.array([[1.0, 0.0, 1.0, 1.0], [2.0, -1.0, 2.0, 0.0]])  # +x meets the first at u = 0, the second at u = 1
    segment_fan(0.0, 0.0, dx, dy, ends, np.arange(2), np.empty((0, 8)), best)
    assert best[0] == 1.0
    segment_fan(0.0, 0.0, dx, dy, ends, np.arange(1, 2), np.empty((0, 8)), best)
    assert best[0] == 2.0


def test_disc_fan_lowers_each_ray_to_its_nearest_disc_by_value():
    from parcover_env.sensors.sonar_fast_kernels import disc_fan

    dx, dy = _fan(4)  # +x, +y, -x, -y
    centres, r = np.array([[2.0, 0.0], [0.0, 3.0], [0.0, -0.05]]), 0.5
    oc = -centres  # origin (0, 0) minus centre
    cc = (oc**2).sum(axis=1) - r * r
    best = np.array([9.0, 1.0, 9.0, 9.0])
    disc_fan(dx, dy, oc[:2, 0].copy(), oc[:2, 1].copy(), cc[:2].copy(), best)
    assert best.tolist() == [1.5, 1.0, 9.0, 9.0]  # +x: 2 - 0.5; +y: 2.5 > the 1.0 it had; -x, -y: miss
    disc_fan(dx, dy, oc[2:, 0].copy(), oc[2:, 1].copy(), cc[2:].copy(), best)
    assert best.tolist() == [0.0, 0.0, 0.0, 0.0]  # the origin inside the third disc: 0 on every ray
    best[:] = 9.0
    disc_fan(dx, dy, np.array([0.5]), np.array([0.0]), np.array([0.0]), best)  # the origin on a disc's rim
    assert best.tolist() == [0.0, 0.0, 0.0, 0.0]  # counts as inside: 0, even on the ray pointing away


def test_fans_equal_the_per_ray_casts_bit_for_bit():
    from parcover_env.geometry.ray_kernels import disc_hit_from, segment_hit
    from parcover_env.sensors.sonar_fast_kernels import disc_fan

    segment_fan = _segment_fan

    rng = np.random.default_rng(3)
    for trial in range(200):
        segs = rng.uniform(-3, 3, (12, 4))
        segs[:3, 2] = segs[:3, 0]  # some axis-parallel walls, so some rays run parallel to a wall
        segs[3:5, 3] = segs[3:5, 1]
        x0, y0 = rng.uniform(-1, 1, 2)
        dx, dy = _fan(16, phase=0.0 if trial % 2 else rng.uniform(-math.pi, math.pi))
        near = np.sort(rng.choice(12, rng.integers(0, 13), replace=False))
        reach, cull = 2.5, bool(trial % 3)
        boxes = np.empty((4 if cull else 0, 16))
        if cull:
            fx, fy = x0 + dx * reach, y0 + dy * reach
            boxes[:] = [np.minimum(x0, fx) - 1e-9, np.maximum(x0, fx) + 1e-9,
                        np.minimum(y0, fy) - 1e-9, np.maximum(y0, fy) + 1e-9]
        walls = np.empty(16)
        segment_fan(x0, y0, dx, dy, segs, near, boxes, walls)
        oc = rng.uniform(-2, 2, (5, 2))
        cc = (oc**2).sum(axis=1) - 0.3**2
        discs = np.full(16, np.inf)
        disc_fan(dx, dy, oc[:, 0].copy(), oc[:, 1].copy(), cc, discs)
        for b in range(16):
            t, i, _ = segment_hit(x0, y0, dx[b], dy[b], segs, near, reach, cull, False)
            assert walls[b] == t and (i >= 0) == (t < np.inf)  # beyond reach too: the caller clips
            assert discs[b] == disc_hit_from(dx[b], dy[b], oc[:, 0], oc[:, 1], cc)
