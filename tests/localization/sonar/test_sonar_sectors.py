"""Visibility sectors from exact geometry: hand-counted rooms, rules 0/1/2, invariance, coverage."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely import affinity

from parcover_env.config import MapConfig
from parcover_env.localization.sonar.features import map_features
from parcover_env.localization.sonar.sectors import compute_sectors, visible_features
from parcover_env.localization.sonar.visibility import DISC_QUAD_SEGS, visibility_region
from parcover_env.viz.sectors import draw_sectors
from parcover_env.world.map_model import MapModel

T_ROOM = MapConfig(size=(4.0, 4.0), boundary=((1.2, 0.0), (2.8, 0.0), (2.8, 2.4), (4.0, 2.4), (4.0, 4.0),
                                              (0.0, 4.0), (0.0, 2.4), (1.2, 2.4)))
L_ROOM = MapConfig(size=(2.0, 2.0), boundary=((0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)))


def counts(m: MapModel, range_max: float = np.inf) -> tuple[int, int, int]:
    f = map_features(m)
    return tuple(len(compute_sectors(m, range_max, rule, f)) for rule in (0, 1, 2))


def moved(m: MapModel, scale: float = 1.0, deg: float = 0.0, shift=(0.0, 0.0)) -> MapModel:
    """The map scaled about the origin, turned about the origin and translated."""
    g = affinity.translate(affinity.rotate(affinity.scale(m.free, scale, scale, origin=(0, 0)), deg,
                                           origin=(0, 0)), *shift)
    return MapModel(free=g, bounds=tuple(float(b) for b in g.bounds))


@pytest.fixture(scope="module")
def room():
    m = MapModel.from_config(T_ROOM)
    return m, map_features(m)


def test_rectangle_is_one_sector():
    """A rectangle: its 4 concave corners are visible from everywhere -> 1 sector for every rule."""
    m = MapModel.from_config(MapConfig(size=(3.0, 2.0)))
    assert len(map_features(m)) == 4
    assert counts(m) == (1, 1, 1)
    (s,) = compute_sectors(m, np.inf, 0)
    assert s.features == s.common == frozenset(range(4)) and s.polygon.area == pytest.approx(6.0)


def test_l_room_hand_count():
    """L room (0,0)-(2,0)-(2,1)-(1,1)-(1,2)-(0,2), unlimited range. Features A(0,0), B(2,0), C(2,1),
    D(1,2), E(0,2); (1,1) is reflex. A sees all; C only the bottom arm (y <= 1), D only the left arm
    (x <= 1); B loses x + y > 2 in the left arm, E loses x + y > 2 in the bottom arm. Faces: the
    square [0,1]^2 {ABCDE}, triangles (1,0)(2,0)(1,1) {ABCE}, (2,0)(2,1)(1,1) {ABC}, (0,1)(1,1)(0,2)
    {ABDE}, (1,1)(1,2)(0,2) {ADE} -> 5 original sectors. Rule #1: closest feature to each centroid
    (square -> A 0.71 m; triangles -> B 0.75, C 0.47, E 0.75, D 0.47) all differ -> 5. Rule #2: A
    is seen from everywhere, so all merge -> 1."""
    m = MapModel.from_config(L_ROOM)
    f = map_features(m)
    assert [tuple(x.point) for x in f] == [(0, 0), (2, 0), (2, 1), (1, 2), (0, 2)]
    s0 = compute_sectors(m, np.inf, 0, f)
    got = {s.features: round(s.polygon.area, 6) for s in s0}  # snap rounding moves vertices by ~1e-9 m
    assert got == {frozenset({0, 1, 2, 3, 4}): 1.0, frozenset({0, 1, 2, 4}): 0.5, frozenset({0, 1, 2}): 0.5,
                   frozenset({0, 1, 3, 4}): 0.5, frozenset({0, 3, 4}): 0.5}
    assert counts(m) == (5, 5, 1)
    (s2,) = compute_sectors(m, np.inf, 2, f)
    assert s2.common == {0} and s2.features == frozenset(range(5))


def test_t_room_hand_count(room):
    """T room (Fig. 3): stem [1.2,2.8]x[0,2.4], bar [0,4]x[2.4,4]; features 0 (1.2,0), 1 (2.8,0),
    2 (4,2.4), 3 (4,4), 4 (0,4), 5 (0,2.4). Bar corners 2 and 5 see the bar only. The stem corners
    see the stem and the bar between x = 1.2 and the line (2.8,2.4)-(3.87,4) (corner 0), or between
    the line (1.2,2.4)-(0.13,4) and x = 2.8 (corner 1). Corner 3 sees the stem above the line
    (2.8,2.4)-(1.2,0.27), corner 4 above (1.2,2.4)-(2.8,0.27). Stem: 4 faces (the two lines cross);
    bar: 5 strips -> 9 original sectors (the two outer strips both see {2,3,4,5} only).
    Rule #1 -> 6, one per feature; the bar's middle strip (centroid (2,3.2), equidistant from 2-5)
    and the stem's bottom face (equidistant from 0 and 1) are ties broken towards a neighbour's
    closest feature (3 and 0). Rule #2 -> 2: bar corners never see the stem."""
    m, f = room
    s0 = compute_sectors(m, np.inf, 0, f)
    assert sorted(sorted(s.features) for s in s0) == sorted(
        [[0, 1], [0, 1, 3], [0, 1, 4], [0, 1, 3, 4], [2, 3, 4, 5], [2, 3, 4, 5], [1, 2, 3, 4, 5],
         [0, 1, 2, 3, 4, 5], [0, 2, 3, 4, 5]])
    assert counts(m) == (9, 6, 2)
    s1 = compute_sectors(m, np.inf, 1, f)
    # the two stem sectors: left of the line (2.8,2.4)-(1.2,0.27) plus the bottom face, and the right one
    stem = sorted(round(s.polygon.area, 6) for s in s1 if s.polygon.centroid.y < 2.4)
    assert stem == pytest.approx([0.853333, 2.986667], abs=1e-6)
    s2 = compute_sectors(m, np.inf, 2, f)
    assert sorted(round(s.polygon.area, 6) for s in s2) == [3.84, 6.4]
    # the AmigoBot's 2.54 m: fewer relaxed than original sectors, and rule 2 merges most
    assert counts(m, 2.54) == (25, 9, 4)


def test_corridor_with_range_hand_count():
    """A 6 m x 1 m corridor, range 2.5 m. Each left corner sees the corridor up to its arc; the arcs
    of (0,0) and (0,1) cross at y = 0.5, so near the left end: both corners, a lower wedge seeing
    (0,0) only, an upper wedge seeing (0,1) only; the same at the right end; between the arcs' outer
    envelopes (x >= sqrt(6) = 2.449 at y = 0.5, 2.5 at the walls) no corner -> 7 original sectors.
    Rule #1: each end face (centroid on y = 0.5, a tie) joins one wedge -> 5. Rule #2: an end face
    joins one wedge, the other wedge shares nothing with the pair -> 5."""
    m = MapModel.from_config(MapConfig(size=(6.0, 1.0)))
    assert counts(m, 2.5) == (7, 5, 5)
    none = [s for s in compute_sectors(m, 2.5, 0) if not s.features]
    x0, _, x1, _ = none[0].polygon.bounds
    assert len(none) == 1 and (x0, x1) == pytest.approx((6 ** 0.5, 6 - 6 ** 0.5), abs=1e-3)


def test_visibility_region_of_a_corner(room):
    """Corner 2 (4, 2.4) of the T room sees exactly the bar; cut by a 1 m range, a quarter disc."""
    m, f = room
    reg = visibility_region(m, f[2].point)
    assert reg.symmetric_difference(shapely.box(0, 2.4, 4, 4)).area < 1e-9
    quarter = visibility_region(m, f[2].point, 1.0)
    n = 4 * DISC_QUAD_SEGS  # the range disc is the inscribed n-gon, a quarter of it here
    assert quarter.area == pytest.approx(n / 2 * np.sin(2 * np.pi / n) / 4, rel=1e-9)
    assert quarter.area == pytest.approx(np.pi / 4, rel=2e-4)


@pytest.mark.parametrize("scale", [0.5, 1.37, 3.0])
@pytest.mark.parametrize("deg", [0.0, 30.0, 90.0])
def test_counts_invariant_to_scale_rotation_translation(room, scale, deg):
    """Counts of t_room, triangle_room and hallway (whose rule #1 has near-ties on symmetry axes)
    do not move when the map is scaled (with the range), turned and translated."""
    m, _ = room
    from parcover_env.scenarios import load_scenario
    from parcover_env.world.map_model import map_model

    tri, hall = (map_model(load_scenario(n).map, include_unknown=False) for n in ("triangle_room", "hallway"))
    for base, expect_inf, expect_r in ((m, (9, 6, 2), (25, 9, 4)), (tri, (11, 4, 2), (10, 6, 6)),
                                       (hall, (38, 14, 4), (35, 19, 15))):
        copy = moved(base, scale, deg, shift=(-7.3, 12.1))
        assert counts(copy) == expect_inf
        assert counts(copy, 2.54 * scale) == expect_r


@pytest.mark.parametrize("rule", [0, 1, 2])
def test_sectors_cover_free_space_and_features_are_visible(room, rule):
    m, f = room
    sectors = compute_sectors(m, 2.54, rule, f)
    union = shapely.union_all([s.polygon for s in sectors])
    assert m.free.symmetric_difference(union).area < 1e-6
    assert sum(s.polygon.area for s in sectors) == pytest.approx(m.free.area, abs=1e-6)  # no overlap
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 4, (3000, 2))
    pts = pts[m.contains(pts)]
    vis = visible_features(pts, m, f, 2.54)  # ray casting, independent of the polygons
    for s in sectors:
        core = s.polygon.buffer(-0.01)
        inside = shapely.contains_xy(core, pts[:, 0], pts[:, 1])
        if not inside.any():
            continue
        seen = vis[inside]
        if rule == 0:  # original sector: the same features from every point
            assert all(set(np.nonzero(row)[0]) == set(s.features) for row in seen)
        else:  # relaxed sector: some feature visible from every point
            assert s.common and all(seen[:, k].all() for k in s.common)
            assert s.common <= s.features


def test_draw_sectors_image(room):
    m, f = room
    img = draw_sectors(m, compute_sectors(m, 2.54, 2, f), f, px_per_m=50)
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 5
    with pytest.raises(ValueError, match="rule"):
        compute_sectors(m, 2.54, 3, f)
    with pytest.raises(ValueError, match="range_max"):
        compute_sectors(m, 0.0, 0, f)


def test_fig3_t_room_scenario_at_unlimited_range():
    """Fig. 3 on the shipped scenario: rule #1 -> 6 sectors (one per feature), rule #2 -> 2."""
    from parcover_env.localization.sonar.sectors import sectors_summary
    from parcover_env.scenarios import load_scenario
    from parcover_env.world.map_model import map_model

    known = map_model(load_scenario("t_room").map, include_unknown=False)
    assert [sectors_summary(known, np.inf, rule)["n_sectors"] for rule in (0, 1, 2)] == [9, 6, 2]
    d = sectors_summary(known, np.inf, 1)
    assert d["range_max"] is None and d["n_features"] == 6
    assert all(len(s["common"]) >= 1 for s in d["sectors"])


def test_fig4_triangle_room_counts():
    """Fig. 4's rules on our room (a 5 m x 4 m rectangle, one triangle; the paper gives no
    coordinates, so its 65 / 7 / 3 are not comparable). Corners 0 (0,0), 1 (5,0), 2 (5,4), 3 (0,4);
    the triangle (1.8,1.4) (3.2,1.4) (2.4,2.6) casts one shadow wedge from each. At unlimited range:
    4 regions see all four corners (left, right, above, and a small triangle on the bottom wall
    between the shadows of 2 and 3, which cross below the triangle), 4 lie in exactly one shadow,
    3 in two (below: 2 and 3; left: 1 and 2; right: 0 and 3; the shadows of 0 and 1 part above the
    apex) -> 11 original sectors, 8 distinct sets. Rule #1 -> 4, rule #2 -> 2."""
    from parcover_env.scenarios import load_scenario
    from parcover_env.world.map_model import map_model

    known = map_model(load_scenario("triangle_room").map, include_unknown=False)
    feats = map_features(known)
    s0, s1, s2 = (compute_sectors(known, np.inf, rule, feats) for rule in (0, 1, 2))
    assert len(feats) == 4 and (len(s0), len(s1), len(s2)) == (11, 4, 2)
    missing = sorted(sorted(set(range(4)) - s.features) for s in s0)
    assert missing == [[], [], [], [], [0], [0, 3], [1], [1, 2], [2], [2, 3], [3]]
    bottom = [s for s in s0 if s.features == frozenset(range(4)) and s.polygon.bounds[3] < 1.4]
    assert len(bottom) == 1 and bottom[0].polygon.bounds[1] == pytest.approx(0.0, abs=1e-6)
