"""The sonar ring's one-pass kernel: the same readings as its parts, walls beyond the range, K worlds,
layouts, robots ignored or absent, argument errors (the rest of the ring: test_sonar.py)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from parcover_env.config import MapConfig, SonarConfig
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.map_model import MapModel

T_ROOM = MapConfig(size=(4.0, 4.0), boundary=((1.2, 0.0), (2.8, 0.0), (2.8, 2.4), (4.0, 2.4), (4.0, 4.0),
                                              (0.0, 4.0), (0.0, 2.4), (1.2, 2.4)),
                   obstacles=(((2.9, 3.0), (3.3, 3.0), (3.3, 3.3), (2.9, 3.3)),))


@pytest.mark.parametrize("change", [{}, {"model": "ray"}, {"multipath": False}, {"crosstalk_prob": 0.0},
                                    {"layout": "amigobot", "crosstalk_prob": 0.7}, {"garbage_rate": 0.2},
                                    {"below_min": "clip", "noise_std": 0.0, "noise_rel": 0.0, "quantization": 0.0},
                                    {"noise_rel": 0.0}, {"noise_std": 0.0}, {"subrays": 3}, {"walls": 1}])
def test_one_pass_ring_equals_its_parts_bit_for_bit(change):
    """``measure`` with a generator casts, cross-talks and adds noise in one compiled call: the same
    readings and the same draws as the noise-free cast, the cross-talk and the noise step by step."""
    from parcover_env.sensors.sonar import crosstalk, simulate_beams

    change = dict(change)
    subrays, n_walls = change.pop("subrays", 5), change.pop("walls", None)
    ring = SonarRing(replace(SonarConfig(crosstalk_prob=0.5), **change), n_subrays=subrays)
    m = MapModel.from_config(T_ROOM)
    walls = m.segments if n_walls is None else m.segments[:n_walls]  # one wall: still specular
    rng = np.random.default_rng(7)
    for n in (1, 2, 9):
        pts = rng.uniform(0.2, 3.8, (200, 2))
        pts = pts[m.contains(pts, margin=0.2)][:n]
        poses = np.column_stack([pts, rng.uniform(-3, 3, n)])
        seed = int(rng.integers(1 << 30))
        a, b = np.random.default_rng(seed), np.random.default_rng(seed)
        one = ring.measure(poses, walls, 0.15, a)
        ideal = simulate_beams(ring.cfg, poses[:, :2], poses[:, 2:3] + ring.beam_angles, walls, poses[:, :2], 0.15,
                               np.arange(n), subrays)
        heard = crosstalk(ring.cfg, poses, ring.beam_angles, walls) if n > 1 else None
        parts = ring._noisy(ideal, heard, b, np.float32)
        assert one.dtype == np.float32 and one.tobytes() == parts.tobytes(), n
        assert a.random() == b.random()  # the same number of draws
        quiet = ring.measure(poses, walls, 0.15, None)  # no generator: the noise-free parts
        assert quiet.tobytes() == ring._noisy(ideal, None, None, np.float32).tobytes()


def test_one_pass_ring_blocks_cross_talk_by_walls_beyond_the_range():
    """Cross-talk travels up to twice the range: robots 4 m apart facing each other with a wall 3 m
    from the first (beyond its 2.54 m range, 1 m from the second) do not hear each other."""
    cfg = SonarConfig(crosstalk_prob=1.0, noise_std=0.0, noise_rel=0.0, quantization=0.0)
    ring = SonarRing(cfg)
    face = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, math.pi]])
    wall = np.array([[3.0, -1.0, 3.0, 1.0]])
    got = ring.measure(face, wall, 0.1, np.random.default_rng(0))
    assert got[0, 0] == np.float32(cfg.range_max) and got[1, 0] == pytest.approx(1.0)  # a wall, no ping
    free = ring.measure(face, np.zeros((0, 4)), 0.1, np.random.default_rng(0))
    assert free[0, 0] == pytest.approx(2.0) and free[1, 0] == pytest.approx(2.0)  # d / 2


def test_readings_of_k_worlds_equal_each_world_measured_alone():
    """K worlds in one compiled call, each with its own draws: world k reads what ``measure`` reads
    for it alone with a generator in the same state (bit for bit); robots hear their own world only."""
    ring = SonarRing(SonarConfig(crosstalk_prob=0.5))
    m = MapModel.from_config(T_ROOM)
    rng = np.random.default_rng(21)
    pts = rng.uniform(0.2, 3.8, (400, 2))
    pts = pts[m.contains(pts, margin=0.2)][:24].reshape(3, 8, 2)
    poses = np.concatenate([pts, rng.uniform(-3, 3, (3, 8, 1))], axis=2)
    for k_worlds in (2, 3):
        gens = [np.random.default_rng(s) for s in range(k_worlds)]
        got = ring.readings(poses[:k_worlds], m.segments, 0.15, [ring.draw(8, g) for g in gens])
        assert got.shape == (k_worlds, 8, ring.n_beams) and got.dtype == np.float32
        for k in range(k_worlds):
            alone = ring.measure(poses[k], m.segments, 0.15, np.random.default_rng(k))
            assert got[k].tobytes() == alone.tobytes()
        assert not np.array_equal(got[0], got[1])


def test_ring_layout_angles_and_subray_count():
    """An evenly spaced ring starts at the heading and steps 360 / n_beams degrees; the scan has one
    reading per ``scan_step_deg``; a ring needs at least one sub-ray."""
    ring = SonarRing(SonarConfig(n_beams=8, scan_step_deg=10.0))
    np.testing.assert_allclose(np.degrees(ring.beam_angles), np.arange(8) * 45.0, atol=1e-12)
    assert len(ring.scan_angles) == 36 and np.degrees(ring.scan_angles[1]) == pytest.approx(10.0)
    assert SonarRing(SonarConfig(), n_subrays=1).n_subrays == 1
    with pytest.raises(ValueError, match="n_subrays must be >= 1, got 0"):
        SonarRing(SonarConfig(), n_subrays=0)


def test_a_ring_that_ignores_robots_sees_only_walls():
    """``include_robots=False``: no robot blocks or echoes, with or without a generator."""
    cfg = SonarConfig(noise_std=0.0, noise_rel=0.0, quantization=0.0, crosstalk_prob=1.0)
    ring = SonarRing(cfg)
    wall = np.array([[2.0, -2.0, 2.0, 2.0]])
    poses = np.array([[1.0, 0.0, math.pi], [0.3, 0.0, 0.0], [0.0, 0.0, 0.0]])  # robot 0 faces the others
    for rng in (None, np.random.default_rng(0)):
        got = ring.measure(poses, wall, 0.1, rng, include_robots=False)
        assert got[0, 0] == np.float32(cfg.range_max) and got[1, 0] == pytest.approx(1.7)
    assert ring.measure(poses, wall, 0.1, None)[0, 0] == pytest.approx(0.6)  # robots seen


def test_no_robots_or_no_beams_read_empty_arrays():
    from parcover_env.sensors.sonar import simulate_beams

    cfg, wall = SonarConfig(), np.array([[1.0, -1.0, 1.0, 1.0]])
    assert simulate_beams(cfg, np.zeros((0, 2)), np.zeros((0, 16)), wall, np.zeros((0, 2)), 0.1,
                          np.zeros(0, dtype=int)).shape == (0, 16)
    assert simulate_beams(cfg, np.zeros((2, 2)), np.zeros((2, 0)), wall, np.zeros((2, 2)), 0.1,
                          np.arange(2)).shape == (2, 0)
    assert SonarRing(cfg).measure(np.zeros((0, 3)), wall, 0.1, np.random.default_rng(0)).shape == (0, 16)


def test_a_ring_reads_walls_and_then_no_walls_as_fresh_rings_do():
    """One ring casts on walls, on none (no specular rules then) and on walls again: each time the
    readings of a new ring."""
    walls = MapModel.from_config(T_ROOM).segments
    poses = np.array([[1.0, 3.0, 0.3], [2.0, 1.0, -1.2], [3.5, 3.2, 2.0]])
    ring = SonarRing(SonarConfig())
    for segs in (walls, np.zeros((0, 4)), walls):
        got = ring.measure(poses, segs, 0.15, np.random.default_rng(5))
        assert np.array_equal(got, SonarRing(SonarConfig()).measure(poses, segs, 0.15, np.random.default_rng(5)))


def test_ring_arguments_are_named_in_errors_and_the_scan_covers_a_turn():
    with pytest.raises(ValueError, match="needs a SonarConfig, got str"):
        SonarRing("specular")
    scan = SonarRing(SonarConfig(scan_step_deg=0.5)).scan_angles
    assert len(scan) == 720 and scan[-1] == pytest.approx(math.radians(359.5))
