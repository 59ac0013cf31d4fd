"""The sonar's compiled loops against plain-Python references that trace every sub-ray of every beam
(both legs, every wall and robot, no culling) and every pair of robots for cross-talk: bit for bit,
with the kernels' float operations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from references import sonar as reference

from parcover_env.config import SonarConfig
from parcover_env.sensors.sonar import SonarRing


def _oblique_room() -> np.ndarray:
    """Walls ``(S, 4)`` of a hexagonal room of oblique walls with a free-standing oblique wall inside."""
    room = np.array([[0.0, 0.0], [4.0, -0.6], [5.2, 1.8], [3.1, 3.9], [1.0, 3.2], [-0.8, 1.5]])
    segs = np.concatenate([room, np.roll(room, -1, axis=0)], axis=1)
    return np.ascontiguousarray(np.concatenate([segs, [[2.0, 1.0, 2.6, 1.9]]]))


def test_disc_culls_change_no_reading():
    """The sonar kernel tests only the discs within range of a robot: bit for bit the readings of
    every sub-ray against every disc, on random crowds and on discs just inside and just outside a
    cone's edge ray and the range."""
    from parcover_env.sensors.sonar import _subray_offsets, simulate_beams

    cfg = SonarConfig(crosstalk_prob=0.0)
    ring = SonarRing(cfg)
    offsets = _subray_offsets(cfg.cone_deg, 5)
    none = np.zeros((0, 4))
    rng = np.random.default_rng(11)
    for _ in range(4):
        xy = rng.uniform(0, 4, (12, 2))
        axes = rng.uniform(-4, 4, (12, 1)) + ring.beam_angles[None, :]
        got = simulate_beams(cfg, xy, axes, none, xy, 0.12, np.arange(12))
        want = reference.disc_echoes(xy, axes, offsets, xy, 0.12, np.arange(12), cfg.range_max)
        assert np.array_equal(got, want) and (got < cfg.range_max).sum() > 20
    # one robot, beam 0 along +x: discs tangent to the cone's edge ray (just hit / just missed), just
    # within / beyond the range, and one the robot stands in
    r, rmax, edge = 0.1, cfg.range_max, offsets[-1]
    dist = 1.5
    cases = []
    for tilt in (-1e-12, 1e-12, -1e-9, 1e-9):
        bearing = edge + math.asin(r / dist) + tilt
        cases.append((dist * math.cos(bearing), dist * math.sin(bearing)))
    cases += [(rmax + r - 1e-9, 0.0), (rmax + r + 1e-9, 0.0), (0.05, 0.0)]
    axes = np.zeros((1, 1))
    for c in cases:
        centres = np.array([[0.0, 0.0], c])
        got = simulate_beams(cfg, np.zeros((1, 2)), axes, none, centres, r, np.array([0]))
        want = reference.disc_echoes(np.zeros((1, 2)), axes, offsets, centres, r, [0], rmax)
        assert got[0, 0] == want[0, 0], c
    hits = [simulate_beams(cfg, np.zeros((1, 2)), axes, none, np.array([[0.0, 0.0], c]), r, np.array([0]))[0, 0]
            for c in cases]
    assert [h < rmax for h in hits] == [True, False, True, False, True, False, True]
    assert hits[-1] == 0.0  # inside a disc: an echo at once


@pytest.mark.parametrize("range_max", [3.0, 1.2])
def test_specular_multipath_echoes_equal_every_path_traced_bit_for_bit(range_max):
    """The compiled cone (near-wall lists, each origin's sub-rays cast as one fan, direct echoes
    before mirrored legs, box and range culls of the second legs) reads bit for bit what tracing
    every sub-ray's two legs against every wall and robot reads, in a room of oblique walls with a
    crowd of robots (a short range: many robots beyond it, left out of the second legs too)."""
    from parcover_env.geometry import rays
    from parcover_env.sensors import sonar_kernels as kern
    from parcover_env.sensors.sonar import _NUDGE, _rules, _share, _subray_offsets, _walls

    cfg = SonarConfig(range_max=range_max)
    ring = SonarRing(cfg)
    walls = _walls(_oblique_room())
    offsets = _subray_offsets(cfg.cone_deg, 5)
    cos_min = math.cos(math.radians(cfg.incidence_max_deg)) - 1e-12
    rng = np.random.default_rng(12)
    n_mirrored = far = 0
    for _ in range(3):
        xy = np.column_stack([rng.uniform(0.3, 3.5, 10), rng.uniform(0.3, 2.8, 10)])
        axes = np.ascontiguousarray(rng.uniform(-4, 4, (10, 1)) + ring.beam_angles[None, :])
        ox, oy = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
        discs = kern.Discs(*rays.disc_planes(xy, 0.15, np.arange(10), 10))
        idx, cnt = rays.near_segments(ox, oy, walls.segments, cfg.range_max)
        got = np.empty((10, ring.n_beams))
        rules = _rules(cfg)  # specular, multipath, box culls
        kern.sonar_echoes(ox, oy, axes, offsets, _share(axes, offsets), walls.kernel, idx, cnt, discs, rules, got)
        for n in range(10):
            others = [tuple(p) for i, p in enumerate(xy) if i != n]
            want = reference.specular_echoes(ox[n], oy[n], axes[n], offsets, walls.segments, walls.kernel.lengths,
                                             others, 0.15 * 0.15, cfg.range_max, cos_min, _NUDGE)
            assert got[n].tobytes() == np.array(want).tobytes(), n
        n_mirrored += int(((got > 2.0 * range_max / 3.0) & np.isfinite(got)).sum())
        far += int((np.hypot(*(xy[:, None] - xy[None]).T) > range_max + 0.15).sum())
    assert n_mirrored > 0 and (far > 0) == (range_max < 3.0)  # two-leg paths; at the short range, far robots


@pytest.mark.parametrize("layout", ["ring", "amigobot"])
def test_crosstalk_equals_a_plain_reference_at_the_cone_edges(layout):
    """Robots at bearings just inside and just outside a beam's cone edge (1e-12 to 1e-5 rad), and
    random robots among walls: the compiled cross-talk (with its cone pre-test) hears exactly what
    every-pair plain Python hears."""
    from parcover_env.sensors.sonar import _half_cone, crosstalk

    cfg = SonarConfig(layout=layout, crosstalk_prob=1.0)
    beams = SonarRing(cfg).beam_angles
    half = _half_cone(cfg)
    none = np.zeros((0, 4))
    inside = outside = 0
    for eps in (1e-12, 1e-9, 1e-7, 1e-5):
        for sign in (-1.0, 1.0):
            for heading in (0.3, -2.0):
                edge = heading + beams[1] + sign * (half + eps)
                for off, j_heading in ((eps, edge + math.pi), (-eps, edge + math.pi - beams[2])):
                    bearing = heading + beams[1] + sign * (half + off)
                    poses = np.array([[0.5, -0.2, heading], [0.5 + 1.2 * math.cos(bearing),
                                                             -0.2 + 1.2 * math.sin(bearing), j_heading]])
                    got = crosstalk(cfg, poses, beams, none)
                    assert np.array_equal(got, reference.crosstalk(cfg, poses, beams, none)), (eps, sign, off)
                    inside += np.isfinite(got[0, 1])
                    outside += np.isinf(got[0, 1])
    assert inside > 4 and outside > 4
    rmax = cfg.range_max  # robots facing each other at twice the range, give or take a little
    for eps in (-1e-9, -1e-13, 0.0, 1e-13, 1e-9):
        d = 2 * rmax + eps
        poses = np.array([[0.3, 0.1, 0.0], [0.3 + d, 0.1, math.pi]])
        got = crosstalk(cfg, poses, beams, none)
        assert np.array_equal(got, reference.crosstalk(cfg, poses, beams, none)), eps
        assert np.isfinite(got[0]).any() == (poses[1, 0] - poses[0, 0] <= 2 * rmax), eps
    walls = _oblique_room()
    rng = np.random.default_rng(3)
    for _ in range(5):
        poses = np.column_stack([rng.uniform(0, 4, (10, 2)), rng.uniform(-4, 4, 10)])
        got = crosstalk(cfg, poses, beams, walls)
        assert np.array_equal(got, reference.crosstalk(cfg, poses, beams, walls)) and np.isfinite(got).any()


def test_overlapping_cones_share_their_common_sub_rays():
    """16 beams 22.5 deg apart with 30 deg cones of 5 sub-rays (7.5 deg apart): a beam's two sub-rays
    on its left are the next beam's two on its right, so 48 rays are traced, not 80; the 72-beam
    scan traces 144 of 360. Beams at other angles, or rows of other patterns, share none."""
    from parcover_env.sensors.sonar import _share, _subray_offsets

    offsets = _subray_offsets(30.0, 5)
    ring = SonarRing(SonarConfig())
    share = _share(ring.beam_angles[None], offsets)
    assert share.shape == (16, 5) and len(np.unique(share)) == 48
    assert share[0].tolist() == [0, 1, 2, 3, 4] and share[1].tolist() == [3, 4, 7, 8, 9]
    assert share[15].tolist() == [73, 74, 77, 0, 1]  # beam 14 on its right, beam 0 (wrapped) on its left
    turned = _share(np.array([[3.0], [-1.0]]) + ring.beam_angles, offsets)  # any heading, same pattern
    assert np.array_equal(turned, share)
    from parcover_env.geometry.angles import wrap_angle

    wrapped = wrap_angle(np.array([[3.0], [-1.0]]) + ring.beam_angles)  # the pattern up to whole turns
    assert np.array_equal(_share(wrapped, offsets), share)
    assert len(np.unique(_share(ring.scan_angles[None], offsets))) == 144
    identity = np.arange(40).reshape(8, 5)
    amigo = SonarRing(SonarConfig(layout="amigobot"))
    assert np.array_equal(_share(amigo.beam_angles[None], offsets), identity)
    mixed = np.stack([amigo.beam_angles, amigo.beam_angles[::-1]])  # rows of different patterns
    assert np.array_equal(_share(mixed, offsets), identity)


def test_each_corner_is_listed_once_at_the_first_of_its_two_walls():
    """A square room (walls 0-3 in order) with a free wall ending on nothing: its four corners are
    listed at walls 0, 0, 1, 2 (the lower index of the two walls meeting there), the free wall lists
    none; the corner echoes found through the near-wall lists equal those with every wall listed."""
    from parcover_env.geometry import rays
    from parcover_env.sensors import sonar_kernels as kern
    from parcover_env.sensors.sonar import _rules, _walls

    square = np.array([[0.0, 0.0, 2.0, 0.0], [2.0, 0.0, 2.0, 2.0], [2.0, 2.0, 0.0, 2.0], [0.0, 2.0, 0.0, 0.0],
                       [0.6, 0.7, 1.1, 1.3]])
    walls = _walls(square)
    owned = walls.kernel.owned
    points = walls.kernel.points
    listed = {tuple(points[c]): s for s in range(len(square)) for c in owned[s] if c >= 0}
    assert listed == {(2.0, 0.0): 0, (0.0, 0.0): 0, (2.0, 2.0): 1, (0.0, 2.0): 2}
    assert (owned[3:] == -1).all() and (owned >= -1).all()
    cfg = SonarConfig(range_max=1.5)
    ox, oy = np.array([0.4, 1.5, 1.0]), np.array([0.3, 1.6, 1.0])
    axes = np.ascontiguousarray(np.linspace(-4, 4, 3)[:, None] + SonarRing(cfg).beam_angles[None, :])
    discs = kern.Discs(*rays.disc_planes(np.zeros((0, 2)), 0.1, np.full(3, -1), 3))
    idx, cnt = rays.near_segments(ox, oy, walls.segments, cfg.range_max)
    got = np.full((3, axes.shape[1]), np.inf)
    kern.sonar_corner_echoes(ox, oy, axes, walls.kernel, idx, cnt, discs, _rules(cfg), got)
    every = np.full((3, axes.shape[1]), np.inf)
    kern.sonar_corner_echoes(ox, oy, axes, walls.kernel, np.tile(np.arange(5), (3, 1)), np.full(3, 5), discs,
                             _rules(cfg), every)
    assert np.array_equal(got, every) and np.isfinite(got).sum() >= 3
    assert np.isclose(got[0][np.isfinite(got[0])], 0.5).all()  # (0.4, 0.3): the corner (0, 0) at 0.5 m


@pytest.mark.parametrize("change", [{}, {"model": "fast", "dropout_prob": 0.2}, {"garbage_rate": 0.3}])
def test_sense_draws_each_world_into_one_array_as_its_own_draw(change):
    """``sense`` of K = 2 worlds (different poses) writes each world's draws into one flat array per
    kind: the readings of each world's own ``draw`` (and of each world alone, K = 1), and every
    generator ends where its own draw leaves it."""
    import copy

    from parcover_env.sensors.base import SensingState

    ring = SonarRing(SonarConfig(**change))
    walls = _oblique_room()
    rng = np.random.default_rng(9)
    poses = np.concatenate([rng.uniform(0.5, 3.0, (2, 4, 2)), rng.uniform(-3, 3, (2, 4, 1))], axis=2)
    gens = [np.random.default_rng(s) for s in (1, 2)]
    mine = [copy.deepcopy(g) for g in gens]
    got = ring.sense(SensingState(poses, walls, 0.15, np.full((2, 4), -1)), gens)
    want = ring.readings(poses, walls, 0.15, [ring.draw(4, g) for g in mine])
    assert np.array_equal(got, want) and got.shape == (2, 4, ring.n_beams)
    for k in range(2):
        alone = ring.sense(SensingState(poses[k:k + 1], walls, 0.15, np.full((1, 4), -1)),
                           [np.random.default_rng(k + 1)])
        assert np.array_equal(alone[0], got[k])
    assert [g.random() for g in gens] == [g.random() for g in mine]
    assert (got < ring.cfg.range_max).sum() > 4


def test_wall_set_of_a_square_room_with_a_collinear_split():
    """Hand-built: a 2 x 1 m room whose bottom wall is split in two at (1, 0) (collinear: no corner) and a
    dangling wall (its free end is no corner): the four room corners, each listed at its lower-indexed wall,
    with the unit directions along its two walls."""
    from parcover_env.sensors.sonar_kernels import wall_set

    segs = np.array([[0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 2.0, 0.0], [2.0, 0.0, 2.0, 1.0], [2.0, 1.0, 0.0, 1.0],
                     [0.0, 1.0, 0.0, 0.0], [0.5, 0.5, 0.7, 0.5]])
    w = wall_set(segs)
    assert np.allclose(w.lengths, [1.0, 1.0, 1.0, 2.0, 1.0, 0.2], rtol=0.0, atol=1e-12)
    assert w.points.tolist() == [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]
    assert w.u1.tolist() == [[1.0, 0.0], [-1.0, 0.0], [0.0, -1.0], [1.0, 0.0]]
    assert w.u2.tolist() == [[0.0, 1.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]
    assert w.owned.tolist() == [[0, -1], [1, -1], [2, -1], [3, -1], [-1, -1], [-1, -1]]


def test_wall_set_is_the_one_vertex_at_a_time_reference_bit_for_bit():
    """The vectorized wall set equals the loop it replaced, every array's bytes: room maps with robots cut
    in as discs (the scan service's team maps), ends off by a rounding step, signed zeros, a lattice of
    random walls with shared, collinear and triple vertices."""
    import shapely

    from parcover_env.sensors.sonar_kernels import wall_set
    from parcover_env.world.map_model import MapModel

    rng = np.random.default_rng(5)
    room = shapely.Polygon([(0, 0), (6, 0), (6, 4), (3, 4), (3, 2.5), (0, 2.5)]).difference(
        shapely.box(1.0, 0.7, 1.6, 1.1))
    sets = []
    for k in range(6):
        discs = shapely.union_all([shapely.Point(*q).buffer(0.165, quad_segs=4)
                                   for q in rng.uniform([0.3, 0.3], [5.7, 2.2], (k, 2))])
        sets.append(MapModel(free=room.difference(discs), bounds=(0, 0, 6, 4)).segments)
    lattice = np.round(rng.uniform(-1.5, 1.5, (400, 4)) * 4) / 4
    lattice[::7] += rng.integers(-2, 3, (len(lattice[::7]), 4)) * 1e-10  # ends within a rounding step
    zeros = np.flatnonzero(lattice == 0.0)
    lattice.flat[zeros[::2]] = -0.0  # signed zeros: a vertex keeps the sign of its first end
    assert len(zeros) > 10
    sets.append(np.ascontiguousarray(lattice))
    sets.append(_oblique_room())
    corners = 0
    for segs in sets:
        got, want = wall_set(segs), reference.wall_set(segs)
        for g, w in zip(got[1:], want, strict=True):
            assert g.shape == w.shape and g.dtype == w.dtype and g.tobytes() == w.tobytes()
        corners += len(want[1])
    assert corners > 100
