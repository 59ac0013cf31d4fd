"""The one ray-casting kernel: hand-built hits, incidence, fans, culling, discs, blocking."""

from __future__ import annotations

import math

import numpy as np
import pytest
from references import rays as reference

from parcover_env.geometry import cast_rays, cast_rays_discs, segments_blocked

WALL = np.array([[2.0, -1.0, 2.0, 1.0]])  # the line x = 2 for |y| <= 1


def _dir(deg: float) -> np.ndarray:
    return np.array([[math.cos(math.radians(deg)), math.sin(math.radians(deg))]])


def test_hit_distance_index_and_incidence_on_a_wall():
    seg = np.vstack([[5.0, 5.0, 6.0, 5.0], WALL])  # index 1 is the wall in front
    h = cast_rays(np.zeros((1, 2)), _dir(25.0), seg, with_cos=True)
    assert h.distance[0] == pytest.approx(2.0 / math.cos(math.radians(25)))
    assert h.index[0] == 1
    assert h.cos_incidence[0] == pytest.approx(math.cos(math.radians(25)))
    # past the wall's end, beyond max_range or pointing away: no hit
    assert cast_rays(np.zeros((1, 2)), _dir(30.0), seg).index[0] == -1  # y = 2 tan 30 > 1
    far = cast_rays(np.zeros((1, 2)), _dir(25.0), seg, 2.0, with_cos=True)
    assert math.isinf(far.distance[0]) and far.index[0] == -1 and far.cos_incidence[0] == 0.0
    back = cast_rays(np.zeros((1, 2)), _dir(180.0), seg)
    assert math.isinf(back.distance[0]) and back.index[0] == -1


def test_fan_of_rays_per_origin_with_and_without_culling():
    origins = np.array([[0.0, 0.0], [1.5, 0.0]])
    angles = np.radians(np.linspace(-40, 40, 40))
    fan = np.broadcast_to(np.stack([np.cos(angles), np.sin(angles)], axis=1), (2, 40, 2))
    walls = np.vstack([WALL, [[10.0, -1.0, 10.0, 1.0]]])
    full = cast_rays(origins, fan, walls, 3.0, cull=False)
    near = cast_rays(origins, fan, walls, 3.0, cull=True)
    assert full.distance.shape == (2, 40)
    np.testing.assert_array_equal(full.distance, near.distance)
    np.testing.assert_allclose(full.distance[1, 20], 0.5 / math.cos(angles[20]))
    # from x = 0 the 2 m-wide wall at 2 m is met within atan(1 / 2) of the axis (in range: 3 m)
    inside = np.abs(angles) <= math.atan(0.5)
    assert np.all(np.isfinite(full.distance[0, inside])) and np.all(np.isinf(full.distance[0, ~inside]))


def test_discs_owner_inside_and_range():
    centres = np.array([[0.0, 0.0], [3.0, 0.0], [1.0, 0.0]])
    d = cast_rays_discs(np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[1.0, 0.0], [1.0, 0.0]]), centres, 0.25,
                        owner=np.array([0, 2]))
    assert d[0] == pytest.approx(0.75)  # own disc ignored, the one at x = 1 hit at 1 - 0.25
    assert d[1] == pytest.approx(1.75)  # from inside its own disc: the next one at 3 - 0.25 - 1
    assert cast_rays_discs(np.zeros((1, 2)), np.array([[1.0, 0.0]]), centres[1:2], 0.25, None, 2.0)[0] == np.inf
    inside = cast_rays_discs(np.array([[3.1, 0.0]]), np.array([[-1.0, 0.0]]), centres[1:2], 0.25)
    assert inside[0] == 0.0


def test_segments_blocked_is_an_open_segment_test():
    a = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    b = np.array([[3.0, 0.0], [1.9, 0.0], [3.0, 3.0]])
    np.testing.assert_array_equal(segments_blocked(a, b, WALL), [True, False, False])
    assert segments_blocked(a, b, np.zeros((0, 4))).tolist() == [False, False, False]


@pytest.mark.parametrize("cull", [False, True])
def test_disc_fans_match_hand_values_with_and_without_culling(cull):
    origins = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.5]])
    angles = np.radians(np.arange(36) * 10.0)
    fan = np.broadcast_to(np.stack([np.cos(angles), np.sin(angles)], axis=1), (3, 36, 2))
    d = cast_rays_discs(origins, fan, origins, np.array([0.2, 0.2, 0.3]), np.arange(3), 3.0, cull=cull)
    assert d.shape == (3, 36)
    assert d[0, 0] == pytest.approx(0.8) and d[1, 18] == pytest.approx(0.8)  # robots 0 and 1 face each other
    assert d[0, 9] == pytest.approx(2.2)  # robot 2 at 2.5 m, radius 0.3
    assert math.isinf(d[1, 0]) and math.isinf(d[2, 9])  # nothing that way (own disc ignored)
    assert d[2, 27] == pytest.approx(2.3)  # robot 0 from robot 2, straight down
    assert math.isinf(d[2, 27 - 3])  # 30 deg off: misses robot 0's disc
    flat = cast_rays_discs(np.repeat(origins, 36, axis=0), fan.reshape(-1, 2), origins, np.array([0.2, 0.2, 0.3]),
                           np.repeat(np.arange(3), 36), 3.0)
    np.testing.assert_array_equal(flat.reshape(3, 36), d)
    far = cast_rays_discs(origins[:1], fan[:1], origins[2:], 0.3, np.array([-1]), 1.0, cull=cull)
    assert np.all(np.isinf(far))


def _random_walls_and_rays(seed: int, n_rays: int):
    rng = np.random.default_rng(seed)
    walls = np.concatenate([rng.uniform(0, 10, (40, 2)), rng.uniform(0, 10, (40, 2))], axis=1)
    walls[:10, 2:] = walls[:10, :2] + rng.uniform(-1, 1, (10, 2))  # short walls
    walls[10, :] = (0.0, 5.0, 10.0, 5.0)  # a horizontal and a vertical wall: degenerate boxes
    walls[11, :] = (5.0, 0.0, 5.0, 10.0)
    origins = rng.uniform(0, 10, (n_rays, 2))
    origins[:5] = walls[20:25, :2]  # rays starting on a wall end
    ang = rng.uniform(-math.pi, math.pi, n_rays)
    dirs = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    dirs[:3] *= 2.5  # non-unit directions: distances in units of their length
    dirs[5] = (1.0, 0.0)  # axis-aligned rays
    dirs[6] = (0.0, -1.0)
    return walls, origins, dirs


@pytest.mark.parametrize("reach", [0.3, 2.0, 30.0])
def test_box_culled_single_rays_equal_the_full_test_bit_for_bit(reach):
    walls, origins, dirs = _random_walls_and_rays(1, 600)
    full = cast_rays(origins, dirs, walls, reach, with_cos=True, cull=False)
    culled = cast_rays(origins, dirs, walls, reach, with_cos=True, cull=True)
    assert np.isfinite(full.distance).sum() > 20  # the comparison sees hits ...
    assert np.isinf(full.distance).sum() > 20  # ... and misses
    assert np.array_equal(full.distance, culled.distance)
    assert np.array_equal(full.index, culled.index)
    assert np.array_equal(full.cos_incidence, culled.cos_incidence)


def test_box_culled_fan_equals_the_full_test_and_ties_take_the_lowest_index():
    walls, origins, _ = _random_walls_and_rays(2, 30)
    ang = np.linspace(-math.pi, math.pi, 64, endpoint=False)
    fan = np.broadcast_to(np.stack([np.cos(ang), np.sin(ang)], axis=1), (30, 64, 2))
    full = cast_rays(origins, fan, walls, 3.0, with_cos=True, cull=False)
    culled = cast_rays(origins, fan, walls, 3.0, with_cos=True, cull=True)
    assert np.array_equal(full.distance, culled.distance) and np.array_equal(full.index, culled.index)
    assert np.array_equal(full.cos_incidence, culled.cos_incidence)
    # two walls meeting at (2, 1): the ray through the shared end hits both at t = 1, reports wall 0
    corner = np.array([[0.0, 1.0, 2.0, 1.0], [2.0, 0.0, 2.0, 1.0], [9.0, 9.0, 9.5, 9.5]])
    hits = cast_rays(np.array([[1.0, 0.0]]), np.array([[1.0, 1.0]]) / math.sqrt(2), corner, 5.0, cull=True)
    assert hits.index[0] == 0 and hits.distance[0] == pytest.approx(math.sqrt(2))
    assert cast_rays(np.array([[1.0, 0.0]]), np.array([[1.0, 0.0]]), corner, 0.5, cull=True).index[0] == -1


def test_box_culled_rays_whose_boxes_meet_walls_they_all_miss():
    """Regression (generated:5): every (ray, wall) box pair misses, so no ray has a nearest hit."""
    walls = np.array([[0.5, 0.1, 0.6, 0.2], [0.1, 0.5, 0.2, 0.7]])  # inside the ray's box, off its line
    origins, dirs = np.zeros((1, 2)), np.array([[0.6, 0.8]])
    for cull in (True, False):
        hits = cast_rays(origins, dirs, walls, 1.0, with_cos=True, cull=cull)
        assert np.isinf(hits.distance[0]) and hits.index[0] == -1 and hits.cos_incidence[0] == 0.0


def test_discs_per_origin_sets_equal_separate_calls():
    """Batched worlds: each origin sees its own disc set; equal to one call per world."""
    rng = np.random.default_rng(4)
    worlds = rng.uniform(0, 4, (3, 5, 2))  # 3 worlds of 5 robots
    ang = rng.uniform(-math.pi, math.pi, (15, 24))
    fan = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
    owner = np.tile(np.arange(5), 3)
    per_origin = np.repeat(worlds, 5, axis=0)  # (15, 5, 2): origin i sees the robots of its world
    for cull in (False, True):
        got = cast_rays_discs(worlds.reshape(15, 2), fan, per_origin, 0.2, owner, 3.0, cull=cull)
        for k in range(3):
            one = cast_rays_discs(worlds[k], fan[5 * k:5 * k + 5], worlds[k], 0.2, np.arange(5), 3.0, cull=cull)
            assert np.array_equal(got[5 * k:5 * k + 5], one)
    # a robot of another world standing right in front of the origin is not seen
    own = cast_rays_discs(np.zeros((1, 2)), np.array([[1.0, 0.0]]), np.array([[[1.0, 0.0], [9.0, 9.0]]]), 0.2,
                          np.array([-1]))
    assert own[0] == pytest.approx(0.8)
    other = cast_rays_discs(np.zeros((1, 2)), np.array([[1.0, 0.0]]), np.array([[[9.0, 9.0], [8.0, 8.0]]]), 0.2,
                            np.array([-1]))
    assert other[0] == math.inf


def test_segments_blocked_equals_the_per_pair_formula():
    walls, a, _ = _random_walls_and_rays(3, 400)
    b = a + np.random.default_rng(5).uniform(-2, 2, (400, 2))
    b[:5] = walls[30:35, 2:]  # ends on a wall end: the open segment does not cross there
    got = segments_blocked(a, b, walls)
    assert 50 < got.sum() < 350 and np.array_equal(got, reference.blocked(a, b, walls))


def test_grazing_rays_on_walls_and_discs():
    """A ray along a wall never hits it (parallel); a ray through a wall's end point hits at the end;
    a ray tangent to a disc hits at the tangent point; one just outside misses."""
    along = cast_rays(np.array([[0.0, 1.0]]), np.array([[1.0, 0.0]]), np.array([[1.0, 1.0, 3.0, 1.0]]))
    assert along.index[0] == -1 and math.isinf(along.distance[0])
    end = cast_rays(np.zeros((1, 2)), np.array([[1.0, 1.0]]) / math.sqrt(2), np.array([[1.0, 1.0, 1.0, 3.0]]),
                    with_cos=True)
    assert end.index[0] == 0 and end.distance[0] == pytest.approx(math.sqrt(2))
    assert end.cos_incidence[0] == pytest.approx(math.cos(math.radians(45)))
    tangent = cast_rays_discs(np.array([[0.0, 0.5]]), np.array([[1.0, 0.0]]), np.array([[2.0, 0.0]]), 0.5)
    assert tangent[0] == pytest.approx(2.0)
    outside = cast_rays_discs(np.array([[0.0, 0.5 + 1e-6]]), np.array([[1.0, 0.0]]), np.array([[2.0, 0.0]]), 0.5)
    assert math.isinf(outside[0])
    # a ray at 60 deg from (0, -3) meets x = 2 at t = 2 / cos 60 = 4, y = -3 + 4 sin 60 = 0.46 (on the wall,
    # |cos| = cos 60); from (0, -2) it meets x = 2 at y = 1.46, past the wall's end
    hit = cast_rays(np.array([[0.0, -3.0]]), _dir(60.0), WALL, with_cos=True)
    assert hit.distance[0] == pytest.approx(4.0) and hit.cos_incidence[0] == pytest.approx(0.5)
    assert cast_rays(np.array([[0.0, -2.0]]), _dir(60.0), WALL).index[0] == -1


@pytest.mark.parametrize("cull", [False, True])
def test_one_origin_shared_by_many_rays(cull):
    """``origins (1, 2)`` with ``directions (R, 2)``: every ray starts at the one origin."""
    dirs = np.vstack([_dir(0.0), _dir(25.0), _dir(180.0)])
    h = cast_rays(np.zeros((1, 2)), dirs, WALL, 10.0, cull=cull)
    np.testing.assert_allclose(h.distance, [2.0, 2.0 / math.cos(math.radians(25)), np.inf])
    with pytest.raises(ValueError, match="do not match"):
        cast_rays(np.zeros((2, 2)), dirs, WALL)


def test_near_segments_lists_the_segments_within_reach_by_point_to_segment_distance():
    from parcover_env.geometry.rays import NEAR_SLACK, near_segments

    segs = np.array([
        [5.0, -1.0, 5.0, 1.0],    # 0: foot of the perpendicular inside, 5 m from the origin
        [-1.0, 1.0, 1.0, 1.0],    # 1: 1 m above
        [3.0, 4.0, 6.0, 8.0],     # 2: nearest point its end (3, 4): 5 m
        [0.5, 0.0, 0.5, 0.0],     # 3: a point 0.5 m away
        [-2.0, -2.0, 2.0, -2.0],  # 4: 2 m below
    ])
    idx, cnt = near_segments(np.array([0.0, 5.0]), np.array([0.0, 0.5]), segs, 2.0)
    assert list(idx[0, :cnt[0]]) == [1, 3, 4]
    assert list(idx[1, :cnt[1]]) == [0]  # (5, 0.5) lies on segment 0; (3, 4) is sqrt(16.25) away
    idx, cnt = near_segments(np.array([0.0]), np.array([0.0]), segs, 5.0)
    assert list(idx[0, :cnt[0]]) == [0, 1, 2, 3, 4]  # 5 m exactly is within
    idx, cnt = near_segments(np.array([0.0]), np.array([0.0]), segs, 2.0 - 2 * NEAR_SLACK)
    assert list(idx[0, :cnt[0]]) == [1, 3]  # segment 4 at 2 m is beyond
    idx, cnt = near_segments(np.array([0.0]), np.array([0.0]), segs, math.inf)
    assert cnt[0] == 5


def test_in_cone_equals_the_wrapped_angle_test():
    from parcover_env.geometry.angles import wrap_angle
    from parcover_env.geometry.ray_kernels import in_cone

    rng = np.random.default_rng(0)
    halves = [0.0, 1e-12, 0.26, math.pi / 2, math.pi - 1e-12, math.pi, 4.0]
    edges = [h + s for h in halves for s in (-1e-15, 0.0, 1e-15)]
    shifted = [e + 2 * math.pi * k for e in edges for k in (-3, 1, 2)]
    angles = np.concatenate([rng.uniform(-25, 25, 4000), edges, shifted, [-e for e in edges]])
    for half in halves:
        want = [bool(abs(wrap_angle(a)) <= half) for a in angles]
        assert [bool(in_cone(a, half)) for a in angles] == want


def test_disc_planes_with_one_radius_equal_the_broadcast_radii():
    """One radius for every disc, and an owner array already in kernel form, give the arrays of the
    general path (radii per disc, owner as a list)."""
    from parcover_env.geometry.rays import disc_planes

    centres = np.array([[0.0, 1.0], [2.0, -1.5], [0.3, 0.4]])
    one = disc_planes(centres, 0.17, np.array([2, -1], dtype=np.int64), 2)
    each = disc_planes(centres, np.full(3, 0.17), [2, -1], 2)
    for a, b in zip(one, each, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert one[2].tolist() == [0.17 * 0.17] * 3 and one[3].tolist() == [2, -1]
    assert disc_planes(centres, 0.1, None, 4)[3].tolist() == [-1] * 4


def test_sight_lines_blocked_equals_the_open_segment_test_per_pair():
    """Point ``i`` to point ``target[i]``: the open-segment test of that pair; False for -1 targets."""
    from parcover_env.geometry import segments_blocked, sight_lines_blocked

    rng = np.random.default_rng(9)
    walls = np.ascontiguousarray(rng.uniform(0, 5, (12, 4)))
    px, py = rng.uniform(0, 5, 40), rng.uniform(0, 5, 40)
    target = rng.integers(-1, 40, 40)
    got = sight_lines_blocked(px, py, target, walls)
    pts = np.column_stack([px, py])
    want = np.where(target >= 0, segments_blocked(pts, pts[np.maximum(target, 0)], walls), False)
    assert np.array_equal(got, want) and 5 < want.sum() < 35
    assert not sight_lines_blocked(px, py, target, np.zeros((0, 4))).any()
    one_wall = np.array([[1.0, -1.0, 1.0, 1.0]])
    assert sight_lines_blocked(np.array([0.0, 2.0, 0.5]), np.zeros(3), np.array([1, -1, 0]), one_wall).tolist() == [
        True, False, False]


def test_segment_fan_gives_each_rays_nearest_wall_its_index_and_den_by_value():
    """Rays at 0, 90, 180 and 270 deg from the origin; walls x = 2 (y in [-1, 1]), a nearer x = 1
    (y in [-1, 0]: only its end at y = 0 lies on +x), y = 3 and a copy of x = 2 listed after it."""
    from parcover_env.geometry.ray_kernels import segment_fan

    segs = np.array([[2.0, -1.0, 2.0, 1.0], [1.0, -1.0, 1.0, 0.0], [-4.0, 3.0, 4.0, 3.0], [2.0, -1.0, 2.0, 1.0]])
    dx, dy = np.array([1.0, 0.0, -1.0, 0.0]), np.array([0.0, 1.0, 0.0, -1.0])
    t, index, dens = np.full(4, -5.0), np.full(4, -5), np.full(4, -5.0)
    segment_fan(0.0, 0.0, dx, dy, segs, np.arange(4), np.empty((0, 4)), t, index, dens)
    assert t.tolist() == [1.0, 3.0, np.inf, np.inf]  # +x: the nearer wall's end (u = 1); +y: y = 3; others miss
    assert index.tolist() == [1, 2, -1, -1] and dens.tolist() == [1.0, -8.0, 0.0, 0.0]  # d x e of the hit
    segment_fan(0.0, 0.0, dx, dy, segs, np.array([0, 2, 3]), np.empty((0, 4)), t, index, dens)
    assert t[0] == 2.0 and index[0] == 0 and dens[0] == 2.0  # the tie with the copy keeps the earlier wall
    segment_fan(0.0, 0.0, dx, dy, segs, np.array([0, 2, 3])[:0], np.empty((0, 4)), t, index, dens)
    assert np.isinf(t).all() and (index == -1).all() and (dens == 0.0).all()  # no walls: reset


def test_segment_fan_equals_the_per_ray_casts_bit_for_bit():
    """Random walls (some axis-parallel: rays parallel to a wall), random listed subsets and fans:
    each ray's ``(t, index, den)`` is :func:`segment_hit`'s without culling, bit for bit."""
    from parcover_env.geometry.ray_kernels import segment_fan, segment_hit

    rng = np.random.default_rng(8)
    hits = 0
    for trial in range(200):
        segs = rng.uniform(-3, 3, (12, 4))
        segs[:3, 2] = segs[:3, 0]
        segs[3:5, 3] = segs[3:5, 1]
        x0, y0 = rng.uniform(-1, 1, 2)
        a = rng.uniform(-math.pi, math.pi) + np.arange(16) * (2 * math.pi / 16) if trial % 2 else \
            np.concatenate([np.arange(8) * (math.pi / 4), rng.uniform(-4, 4, 8)])
        dx, dy = np.cos(a), np.sin(a)
        near = np.sort(rng.choice(12, rng.integers(0, 13), replace=False))
        t, index, dens = np.empty(16), np.empty(16, np.int64), np.empty(16)
        segment_fan(x0, y0, dx, dy, segs, near, np.empty((0, 16)), t, index, dens)
        for b in range(16):
            want = segment_hit(x0, y0, dx[b], dy[b], segs, near, np.inf, False, False)
            assert (t[b], index[b], dens[b]) == want
            hits += index[b] >= 0
    assert 1000 < hits < 3000
