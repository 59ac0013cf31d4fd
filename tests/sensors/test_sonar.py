"""Sonar ring model: vectorized vs brute-force reference, specular physics, noise, blocking."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from references import sonar as reference

from parcover_env.config import MapConfig, SonarConfig
from parcover_env.sensors.sonar import SonarRing
from parcover_env.world.map_model import MapModel

T_ROOM = MapConfig(size=(4.0, 4.0), boundary=((1.2, 0.0), (2.8, 0.0), (2.8, 2.4), (4.0, 2.4), (4.0, 4.0),
                                              (0.0, 4.0), (0.0, 2.4), (1.2, 2.4)),
                   obstacles=(((2.9, 3.0), (3.3, 3.0), (3.3, 3.3), (2.9, 3.3)),))


@pytest.mark.parametrize("model", ["ray", "specular"])
def test_vectorized_matches_brute_force(model):
    m = MapModel.from_config(T_ROOM)
    cfg = SonarConfig(model=model, n_beams=12, quantization=0.0, multipath=False, below_min="clip")
    ring = SonarRing(cfg)
    rng = np.random.default_rng(3)
    pts = rng.uniform(0, 4, (400, 2))
    pts = pts[m.contains(pts, margin=0.2)][:12]
    poses = np.column_stack([pts, rng.uniform(-math.pi, math.pi, len(pts))])
    got = ring.measure(poses, m.segments, 0.165, None)
    for i, pose in enumerate(poses):
        others = [p[:2] for j, p in enumerate(poses) if j != i]
        want = reference.beams(cfg, pose[:2], pose[2] + ring.beam_angles, m.segments, others, 0.165)
        np.testing.assert_allclose(got[i], np.maximum(want, cfg.range_min), atol=1e-4)
    scan = ring.scan(poses[0], m.segments, poses[1:, :2], 0.165, None)
    want = reference.beams(cfg, poses[0, :2], poses[0, 2] + ring.scan_angles, m.segments, poses[1:, :2], 0.165)
    np.testing.assert_allclose(scan, np.maximum(want, cfg.range_min), atol=1e-6)
    assert scan.shape == (72,)


def _box_room():
    return MapModel.from_config(MapConfig(size=(10.0, 10.0)))


def test_specular_perpendicular_wall_echoes_oblique_does_not():
    m = _box_room()
    ring = SonarRing(SonarConfig(model="specular", n_beams=4, noise_std=0, noise_rel=0, quantization=0))
    # 1.0 m from the left wall, facing it; everything else beyond range
    pose = np.array([[1.0, 5.0, math.pi]])
    r = ring.measure(pose, m.segments, 0.165, None)[0]
    assert r[0] == pytest.approx(1.0, abs=1e-6)  # beam 0 points at the wall: normal incidence
    # 50 deg off the normal (beyond cone/2 + incidence_max = 35 deg): no echo
    r = ring.measure(np.array([[1.0, 5.0, math.pi + math.radians(50)]]), m.segments, 0.165, None)[0]
    assert r[0] == pytest.approx(2.54)
    # the ideal ray model still sees the oblique wall
    ray = SonarRing(SonarConfig(model="ray", n_beams=4, quantization=0.0))
    r = ray.measure(np.array([[1.0, 5.0, math.pi + math.radians(50)]]), m.segments, 0.165, None)[0]
    assert r[0] == pytest.approx(1.0 / math.cos(math.radians(50)), abs=1e-6)


def test_specular_concave_corner_retro_reflects():
    m = _box_room()
    ring = SonarRing(SonarConfig(model="specular", n_beams=8, quantization=0.0))
    pose = np.array([[1.2, 1.2, math.radians(225)]])  # beam 0 points into the corner (0, 0), 45 deg off both
    r = ring.measure(pose, m.segments, 0.165, None)[0]
    assert r[0] == pytest.approx(math.hypot(1.2, 1.2), abs=1e-6)


def test_other_robots_block_and_can_be_excluded():
    m = _box_room()
    ring = SonarRing(SonarConfig(model="specular", n_beams=8, quantization=0.0))
    poses = np.array([[5.0, 5.0, 0.0], [6.0, 5.0, math.pi]])
    r = ring.measure(poses, m.segments, 0.2, None)
    assert r[0, 0] == pytest.approx(0.8, abs=1e-6) and r[1, 0] == pytest.approx(0.8, abs=1e-6)
    r = ring.measure(poses, m.segments, 0.2, None, include_robots=False)
    assert r[0, 0] == pytest.approx(2.54)


def test_noise_quantization_clamp_and_garbage():
    m = _box_room()
    cfg = SonarConfig(model="ray", n_beams=1, noise_std=0.02, noise_rel=0.0, quantization=0.01)
    ring = SonarRing(cfg)
    rng = np.random.default_rng(0)
    poses = np.tile([[1.0, 5.0, math.pi]], (2000, 1))
    r = ring.measure(poses, m.segments, 0.1, rng, include_robots=False)[:, 0].astype(float)
    assert r.dtype == float and abs(r.mean() - 1.0) < 0.003 and 0.017 < r.std() < 0.023
    np.testing.assert_allclose(np.round(r / 0.01) * 0.01, r, atol=1e-5)
    # an echo nearer than range_min is lost (reads range_max) by default, or clipped
    near = ring.measure([[0.05, 5.0, math.pi]], m.segments, 0.1, rng)[0, 0]
    assert near == pytest.approx(cfg.range_max)
    clip = SonarRing(replace(cfg, below_min="clip"))
    assert clip.measure([[0.05, 5.0, math.pi]], m.segments, 0.1, rng)[0, 0] == pytest.approx(cfg.range_min)
    bad = SonarRing(replace(cfg, garbage_rate=1.0, noise_std=0.0))
    g = bad.measure(poses[:200], m.segments, 0.1, rng, include_robots=False)
    assert np.all((g >= cfg.range_min) & (g <= cfg.range_max)) and g.std() > 0.3


def test_layouts_and_bad_input():
    assert SonarRing(SonarConfig(layout="amigobot")).n_beams == 8
    assert SonarRing(SonarConfig(n_beams=16)).beam_angles.shape == (16,)
    ring = SonarRing(SonarConfig())
    segs = _box_room().segments
    with pytest.raises(ValueError, match=r"^poses must have shape \(N, 3\), got \(2, 2\)$"):
        ring.measure(np.zeros((2, 2)), segs, 0.1, None)
    with pytest.raises(ValueError, match=r"^segments must have shape \(N, 4\), got \(3, 3\)$"):
        ring.measure(np.zeros((1, 3)), np.zeros((3, 3)), 0.1, None)
    with pytest.raises(ValueError, match="NaN"):
        ring.scan([np.nan, 0, 0], segs, None, 0.1, None)
    with pytest.raises(ValueError, match="SonarConfig"):
        SonarRing({"model": "ray"})


@pytest.mark.parametrize("model", ["ray", "specular"])
def test_ideal_batch_equals_measure_per_world_bit_for_bit(model):
    """K worlds in one cast (walls shared, robots per world) = the noise-free ring of each world alone."""
    cfg = SonarConfig(model=model, multipath=model == "specular", crosstalk_prob=0.0, noise_std=0.0,
                      noise_rel=0.0, quantization=0.0)
    ring = SonarRing(cfg)
    walls = np.array([[0, 0, 6, 0], [6, 0, 6, 4], [6, 4, 0, 4], [0, 4, 0, 0], [2, 1, 3, 2.5]], dtype=float)
    rng = np.random.default_rng(0)
    poses = np.concatenate([rng.uniform(0.3, 3.7, (4, 6, 2)) * [1.5, 1.0], rng.uniform(-3, 3, (4, 6, 1))], axis=2)
    batch = ring.ideal_batch(poses, walls, 0.2)
    assert batch.shape == (4, 6, ring.n_beams)
    for k in range(4):
        one = ring.measure(poses[k], walls, 0.2, None)
        assert np.array_equal(ring.corrupt(batch[k], None).astype(np.float32), one)
        assert np.array_equal(ring._noisy(batch[k], None, None, np.float32), one)
    # robots of world 1 are not in world 0: moving them leaves world 0's readings unchanged
    moved = poses.copy()
    moved[1, :, :2] = poses[0, :, :2] + 0.05
    again = ring.ideal_batch(moved, walls, 0.2)
    assert np.array_equal(again[0], batch[0]) and not np.array_equal(again[1], batch[1])


def test_crosstalk_batched_over_worlds_equals_each_world_alone():
    from parcover_env.sensors.sonar import crosstalk

    cfg = SonarConfig(crosstalk_prob=0.5)
    ring = SonarRing(cfg)
    walls = np.array([[3.0, -5.0, 3.0, 0.5]])  # a wall between some of the robots
    rng = np.random.default_rng(2)
    poses = np.concatenate([rng.uniform(0, 6, (5, 7, 2)), rng.uniform(-3, 3, (5, 7, 1))], axis=2)
    both = crosstalk(cfg, poses, ring.beam_angles, walls)
    assert np.isfinite(both).sum() > 10
    for k in range(5):
        assert np.array_equal(both[k], crosstalk(cfg, poses[k], ring.beam_angles, walls))
    # hand-built: two robots 2 m apart facing each other, beam 0 of each on the other: reads d / 2 = 1 m
    face = np.array([[[0.0, 0.0, 0.0], [2.0, 0.0, math.pi]]])
    got = crosstalk(cfg, face, ring.beam_angles, np.zeros((0, 4)))
    assert got[0, 0, 0] == pytest.approx(1.0) and got[0, 1, 0] == pytest.approx(1.0)
    assert np.isinf(got[0, 0, 8])  # the beam pointing away hears nothing
    blocked = crosstalk(cfg, face, ring.beam_angles, np.array([[1.0, -1.0, 1.0, 1.0]]))
    assert np.isinf(blocked).all()


@pytest.mark.parametrize("range_max", [0.8, 1.5, 3.0, 50.0])
def test_near_wall_lists_change_no_reading(monkeypatch, range_max):
    """The sonar kernels look walls up in each robot's list of those within reach; with every wall
    listed instead (the lists' slack made huge, every list from ``near_segments`` full), readings and
    cross-talk are the same bit for bit (also short ranges, where the lists leave most walls out)."""
    from parcover_env.geometry import rays
    from parcover_env.sensors import sonar
    from parcover_env.sensors.sonar import crosstalk

    cfg = SonarConfig(range_max=range_max, crosstalk_prob=0.5)
    ring = SonarRing(cfg)
    m = MapModel.from_config(T_ROOM)
    rng = np.random.default_rng(5)
    poses = np.concatenate([rng.uniform(0.2, 3.8, (3, 12, 2)), rng.uniform(-3, 3, (3, 12, 1))], axis=2)
    ideal, heard = ring.ideal_batch(poses, m.segments, 0.1), crosstalk(cfg, poses, ring.beam_angles, m.segments)
    scan = ring.scan(poses[0, 0], m.segments, poses[0, 1:, :2], 0.1, None)
    counts = rays.near_segments(poses[..., 0].ravel(), poses[..., 1].ravel(), np.ascontiguousarray(m.segments),
                                range_max)[1]

    def every(ox, oy, segments, reach):
        return np.tile(np.arange(len(segments)), (len(ox), 1)), np.full(len(ox), len(segments))

    def wide(*args, **kwargs):
        rules = rules_of(*args, **kwargs).copy()
        rules["near_slack"] = 1e9
        return rules

    rules_of = sonar._rules
    monkeypatch.setattr(rays, "near_segments", every)
    monkeypatch.setattr(sonar, "_rules", wide)
    assert np.array_equal(ring.ideal_batch(poses, m.segments, 0.1), ideal)
    assert np.array_equal(crosstalk(cfg, poses, ring.beam_angles, m.segments), heard)
    assert np.array_equal(ring.scan(poses[0, 0], m.segments, poses[0, 1:, :2], 0.1, None), scan)
    if range_max < 1:
        assert counts.mean() < 0.5 * len(m.segments)  # the lists do leave walls out
    assert (ideal < range_max).any()


@pytest.mark.parametrize("change", [{}, {"below_min": "clip"}, {"garbage_rate": 0.2}, {"quantization": 0.0},
                                    {"noise_std": 0.0, "noise_rel": 0.0}, {"noise_std": 0.0}, {"noise_rel": 0.0},
                                    {"crosstalk_prob": 0.0}])
def test_compiled_noise_equals_the_numpy_formulas_bit_for_bit(change):
    cfg = replace(SonarConfig(crosstalk_prob=0.3, noise_std=0.02, noise_rel=0.03, quantization=0.005), **change)
    ring = SonarRing(cfg)
    draw = np.random.default_rng(4)
    ideal = draw.uniform(0.0, cfg.range_max * 1.2, (9, ring.n_beams))
    ideal[0, :3] = [cfg.range_min / 2, cfg.range_max, 0.0]
    heard = np.where(draw.random(ideal.shape) < 0.5, draw.uniform(0.0, 2.0, ideal.shape), np.inf)
    talk = cfg.crosstalk_prob > 0
    got = ring._noisy(ideal, heard if talk else None, np.random.default_rng(8), np.float32)
    want = reference.noise(cfg, ideal, heard if talk else None, np.random.default_rng(8))
    assert got.dtype == np.float32 and np.array_equal(got, want.astype(np.float32))
    rng_a, rng_b = np.random.default_rng(1), np.random.default_rng(1)
    scan = ring.corrupt(ideal[0], rng_a)  # 1-D, float64
    assert scan.dtype == np.float64 and np.array_equal(scan, reference.noise(cfg, ideal[0], None, rng_b))
    assert rng_a.random() == rng_b.random()  # the same number of draws
    assert np.array_equal(ring.corrupt(ideal, None), reference.noise(cfg, ideal, None, None))


def test_ring_cones_cover_the_circle_only_when_the_gaps_are_narrower_than_a_cone():
    from parcover_env.sensors.sonar import _covers_circle

    ring16 = np.arange(16) * (2 * math.pi / 16)  # 22.5 deg apart
    assert _covers_circle(ring16.tobytes(), math.radians(15))
    assert not _covers_circle(ring16.tobytes(), math.radians(11.25))  # cones just touch: not covered
    amigo = np.radians(np.array([90.0, 44.0, 12.0, -12.0, -44.0, -90.0, -144.0, 144.0]))
    assert not _covers_circle(amigo.tobytes(), math.radians(35))  # 72 deg gap at the back
    assert _covers_circle(amigo.tobytes(), math.radians(37))
    assert not _covers_circle(np.zeros(0).tobytes(), math.pi)


def test_crosstalk_needs_a_beam_pointing_back_when_the_cones_leave_gaps():
    """AmigoBot layout, 30 deg cones: the robot ahead faces away, its rear beams (+-144 deg) leave
    the direction straight back uncovered, so it cannot ping back; turned around, it can."""
    from parcover_env.sensors.sonar import AMIGOBOT_ANGLES_DEG, crosstalk

    cfg = SonarConfig(layout="amigobot", crosstalk_prob=1.0)
    beams = np.radians(np.array(AMIGOBOT_ANGLES_DEG))
    away = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    facing = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, math.pi]])
    assert np.isinf(crosstalk(cfg, away, beams, np.zeros((0, 4)))[0]).all()
    heard = crosstalk(cfg, facing, beams, np.zeros((0, 4)))[0]
    assert heard[2] == heard[3] == 0.5 and np.isinf(heard[[0, 1, 4, 5, 6, 7]]).all()  # +-12 deg beams


def test_a_mirrored_sub_ray_reads_its_two_leg_path_only_with_multipath():
    """A 45 deg wall 1 m ahead mirrors the beam up to a wall 0.8 m above the bounce: with multipath
    the cone's nearest echo is a two-leg path of about 1.8 m; without it, or with the second wall
    gone, nothing echoes (the oblique wall alone is too oblique)."""
    from parcover_env.sensors.sonar import simulate_beams

    oblique = [0.5, -0.5, 1.5, 0.5]
    above = [0.5, 0.8, 1.5, 0.8]
    origin, axes, none = np.zeros((1, 2)), np.zeros((1, 1)), np.zeros((0, 2))

    def read(walls, multipath):
        cfg = SonarConfig(multipath=multipath, crosstalk_prob=0.0, range_max=3.0)
        return simulate_beams(cfg, origin, axes, np.array(walls, dtype=float), none, 0.1, np.array([-1]), 5)[0, 0]

    two_legs = read([oblique, above], True)
    assert 1.6 < two_legs <= 1.8 + 1e-6
    assert read([oblique, above], False) == 3.0
    assert read([oblique], True) == 3.0  # one wall, oblique: no echo
    cfg = SonarConfig(multipath=True, crosstalk_prob=0.0, range_max=3.0)  # 5 sub-rays by default
    assert simulate_beams(cfg, origin, axes, np.array([oblique, above]), none, 0.1, np.array([-1]))[0, 0] == two_legs


def test_measure_hears_the_facing_robot_and_draws_only_what_it_needs():
    """Two robots 2 m apart facing each other, cross-talk certain, no noise: each front beam reads
    the other's ping at d / 2 = 1 m (nearer than the 1.9 m echo off its body). One robot alone, or
    no generator, draws no cross-talk number."""
    cfg = SonarConfig(crosstalk_prob=1.0, noise_std=0.0, noise_rel=0.0, quantization=0.0)
    ring = SonarRing(cfg)
    face = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, math.pi]])
    walls = np.zeros((0, 4))
    got = ring.measure(face, walls, 0.1, np.random.default_rng(0))
    assert got[0, 0] == pytest.approx(1.0) and got[1, 0] == pytest.approx(1.0)
    quiet = ring.measure(face, walls, 0.1, None)
    assert quiet[0, 0] == pytest.approx(1.9) and quiet[1, 0] == pytest.approx(1.9)
    rng, ref = np.random.default_rng(3), np.random.default_rng(3)
    ring.measure(face[:1], walls, 0.1, rng)
    assert rng.random() == ref.random()  # one robot: no cross-talk draws (and no noise here)
    ring.measure(face, walls, 0.1, rng, include_robots=False)
    assert rng.random() == ref.random()


def test_crosstalk_of_k_worlds_has_k_rows():
    from parcover_env.sensors.sonar import crosstalk

    ring = SonarRing(SonarConfig(crosstalk_prob=0.5))
    poses = np.zeros((3, 5, 3))
    poses[..., 0] = np.arange(5)
    assert crosstalk(ring.cfg, poses, ring.beam_angles, np.zeros((0, 4))).shape == (3, 5, ring.n_beams)


def test_corrupt_keeps_the_shape_of_a_scalar():
    ring = SonarRing(SonarConfig(noise_std=0.0, noise_rel=0.0, quantization=0.1))
    one = ring.corrupt(1.26, None)
    assert one.shape == () and one == pytest.approx(1.3)
    lost = ring.cfg.range_max  # below range_min: lost, reads "too far"
    assert ring.corrupt(np.array([1.26, 0.05]), None).tolist() == pytest.approx([1.3, lost])


def test_crosstalk_of_wanted_beams_only():
    """``want`` computes only those beams: the same values there, inf elsewhere."""
    from parcover_env.sensors.sonar import crosstalk

    cfg = SonarConfig(crosstalk_prob=0.5)
    ring = SonarRing(cfg)
    walls = np.array([[3.0, -5.0, 3.0, 0.5]])
    rng = np.random.default_rng(4)
    poses = np.concatenate([rng.uniform(0, 6, (3, 9, 2)), rng.uniform(-3, 3, (3, 9, 1))], axis=2)
    full = crosstalk(cfg, poses, ring.beam_angles, walls)
    want = rng.random(full.shape) < 0.3
    got = crosstalk(cfg, poses, ring.beam_angles, walls, want)
    assert np.array_equal(got, np.where(want, full, np.inf)) and np.isfinite(got).sum() > 5
    assert np.array_equal(crosstalk(cfg, poses[1], ring.beam_angles, walls, want[1]), got[1])
    assert np.isinf(crosstalk(cfg, poses, ring.beam_angles, walls, np.zeros_like(want))).all()


def test_a_read_only_wall_array_is_checked_once_a_writable_one_every_call():
    """A map's walls are a read-only array: the ring checks them the first time only and keys its
    wall data on the array; walls in a writable array are checked at every call."""
    from parcover_env.sensors import sonar

    ring = SonarRing(SonarConfig())
    pose = np.array([[1.0, 1.0, 0.0]])
    walls = np.array([[3.0, -1.0, 3.0, 3.0], [0.0, 0.0, 0.0, 2.0]])
    frozen = walls.copy()
    frozen.setflags(write=False)
    want = ring.measure(pose, walls, 0.1, None)
    assert np.array_equal(ring.measure(pose, frozen, 0.1, None), want)
    assert ring._checked is frozen and sonar._walls(frozen) is sonar._walls(frozen)
    moved = ring.measure(pose, walls, 0.1, None)
    walls[0, [0, 2]] = 2.0  # moved in place, 1 m nearer: a writable array is read afresh
    assert moved[0, 0] == pytest.approx(2.0) and ring.measure(pose, walls, 0.1, None)[0, 0] == pytest.approx(1.0)
    walls[0, 0] = np.nan
    with pytest.raises(ValueError, match="segments contains NaN"):
        ring.measure(pose, walls, 0.1, None)
    bad = walls.copy()
    bad.setflags(write=False)
    with pytest.raises(ValueError, match="segments contains NaN"):  # a new read-only array: checked
        ring.measure(pose, bad, 0.1, None)
    assert ring._checked is None  # the last array checked was writable; the failed one is not kept
