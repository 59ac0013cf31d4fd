"""The exact shortcuts of a 360-degree sonar scan's kernels (issue 40): each wall tested only against the
rays of its angular span (:func:`~parcover_env.geometry.ray_kernels.segment_fan_spans`), second legs
traced only as far as the cone's best echo, and the corner echoes' early-exit line of sight
(:func:`~parcover_env.geometry.ray_kernels.wall_before`) and beam pick on an even fan: values on
hand-built rooms, and bit for bit what the kernels without them (or the plain references) give."""

from __future__ import annotations

import math

import numpy as np
import pytest
from references import sonar as reference

from parcover_env.config import SonarConfig
from parcover_env.geometry import ray_kernels as rk
from parcover_env.geometry import rays
from parcover_env.sensors import sonar_kernels as kern
from parcover_env.sensors.sonar import _NUDGE, SonarRing, _rules, _share, _subray_offsets, _walls

SQUARE = np.array([[0.0, 0.0, 4.0, 0.0], [4.0, 0.0, 4.0, 4.0], [4.0, 4.0, 0.0, 4.0], [0.0, 4.0, 0.0, 0.0]])
"""A 4 m square room, walls in counter-clockwise order (bottom, right, top, left)."""


def _scan_fan(heading: float) -> tuple[np.ndarray, np.ndarray]:
    """The unit directions of a 72-beam scan's 144 traced sub-rays at ``heading`` (rad), in slot order,
    as :func:`~parcover_env.sensors.sonar_kernels.sonar_echoes` computes them."""
    ring = SonarRing(SonarConfig())
    offsets = _subray_offsets(30.0, 5)
    axes = heading + ring.scan_angles
    share = _share(axes[None], offsets)
    dx, dy = [], []
    for b in range(len(axes)):
        for j in range(5):
            if share[b, j] == b * 5 + j:
                ax, ay = math.cos(axes[b]), math.sin(axes[b])
                co, so = math.cos(offsets[j]), math.sin(offsets[j])
                dx.append(ax * co - ay * so)
                dy.append(ay * co + ax * so)
    return np.array(dx), np.array(dy)


def _both_fans(x0, y0, dx, dy, segs, order=None):
    """``(segment_fan, segment_fan_spans)`` outputs ``(t, index, dens)`` of the fan on every wall."""
    near = np.arange(len(segs))
    plain = (np.empty(len(dx)), np.empty(len(dx), dtype=np.int64), np.empty(len(dx)))
    rk.segment_fan(x0, y0, dx, dy, segs, near, np.empty((0, len(dx))), *plain)
    order = np.arange(len(dx)) if order is None else order
    spans = (np.empty(len(dx)), np.empty(len(dx), dtype=np.int64), np.empty(len(dx)))
    rk.segment_fan_spans(x0, y0, dx, dy, segs, near, order, np.empty(len(dx)), *spans)
    return plain, spans


def _same(a, b) -> bool:
    return all(x.tobytes() == y.tobytes() for x, y in zip(a, b, strict=True))


def test_pseudo_angle_is_monotone_and_quarters_a_turn():
    assert [rk.pseudo_angle(*v) for v in ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0), (1.0, 1.0))] == \
        [0.0, 1.0, 2.0, 3.0, 0.5]
    ang = np.linspace(0.0, 2 * math.pi, 2001)[:-1]
    keys = np.array([rk.pseudo_angle(math.cos(a), math.sin(a)) for a in ang])
    assert (np.diff(keys) > 0).all() and keys.min() >= 0.0 and keys.max() < 4.0
    slope = np.diff(keys) / np.diff(ang)  # between 1/2 and 1 per radian (the margin's premise)
    assert slope.min() > 0.5 - 1e-3 and slope.max() < 1.0 + 1e-3


def test_span_fan_hits_the_walls_at_their_distances_and_equals_the_plain_fan():
    """From (1, 1) in the square room, the scan's ray along +x hits the right wall (index 1) at 3 m, the
    one along +y the top wall (2) at 3 m, the one along -x the left wall (3) at 1 m; every ray's hit,
    wall and ``d x e`` equal the plain fan's bit for bit."""
    dx, dy = _scan_fan(0.0)
    plain, spans = _both_fans(1.0, 1.0, dx, dy, SQUARE)
    assert _same(plain, spans)
    t, index, _ = spans
    for (ux, uy), wall, dist in (((1.0, 0.0), 1, 3.0), ((0.0, 1.0), 2, 3.0), ((-1.0, 0.0), 3, 1.0)):
        r = int(np.argmax(dx * ux + dy * uy))  # the ray along that direction
        assert index[r] == wall and t[r] == pytest.approx(dist, abs=1e-12)
    assert (index >= 0).all()  # a closed room: every ray hits a wall


def test_span_fan_guard_cases_and_a_reused_order_equal_the_plain_fan():
    """An origin on a wall's line (the guard: that wall against every ray), a wall through the origin,
    a tiny wall, a degenerate one, walls crossing +x (the keys' wrap), a wall hit exactly at its end
    (``u`` = 1); the ray order kept from a fan turned a little; random walls: all bit for bit."""
    segs = np.array([[-1.0, 0.0, 3.0, 0.0],  # the origin lies on its line (and on it)
                     [0.5, -0.5, 0.5, 0.5],  # crosses +x (keys wrap at 0 / 4)
                     [1.0, 1.0, 1.0 + 1e-7, 1.0],  # tiny
                     [2.0, 2.0, 2.0, 2.0],  # degenerate
                     [-2.0, -1.0, -2.0, 1.0],
                     [1.0, -1.0, -1.0, -1.0 + 1e-15],
                     [0.0, 2.0, 1.0, 2.0]])  # hit at its end by the +45 degree ray? (u = 1 exactly at (1, 2)?)
    order = np.arange(144)
    for heading in (0.0, 1e-3, 0.5, 2.0, -3.0, math.pi):
        dx, dy = _scan_fan(heading)
        plain, spans = _both_fans(0.0, 0.0, dx, dy, segs, order)  # order: kept from the last heading
        assert _same(plain, spans), heading
        assert sorted(order.tolist()) == list(range(144))
    rng = np.random.default_rng(5)
    dx, dy = _scan_fan(0.3)
    for _ in range(30):
        walls = rng.uniform(-3, 3, (25, 4))
        o = rng.uniform(-2, 2, 2)
        plain, spans = _both_fans(o[0], o[1], dx, dy, walls)
        assert _same(plain, spans) and (plain[1] >= 0).sum() > 10


def test_wall_before_finds_a_wall_nearer_than_the_limit():
    """From (1, 1) along +x the right wall lies at exactly 3 m: a wall before 3 + 1e-9 m, none before 3 m
    (strictly), none before 5 m along +x from outside the room's far wall; random rays agree with the
    nearest hit of ``segment_hit``."""
    every = np.arange(4)
    assert rk.wall_before(1.0, 1.0, 1.0, 0.0, SQUARE, every, 3.0 + 1e-9, 3.0 + 1e-9)
    assert not rk.wall_before(1.0, 1.0, 1.0, 0.0, SQUARE, every, 3.0, 3.0)
    assert not rk.wall_before(4.5, 1.0, 1.0, 0.0, SQUARE, every, 5.0, 5.0)
    rng = np.random.default_rng(8)
    segs = rng.uniform(0, 4, (30, 4))
    idx = np.arange(30)
    n_true = 0
    for _ in range(300):
        x, y, a, limit = *rng.uniform(0, 4, 2), rng.uniform(-4, 4), rng.uniform(0.1, 3)
        t, _, _ = rk.segment_hit(x, y, math.cos(a), math.sin(a), segs, idx, np.inf, False, False)
        got = rk.wall_before(x, y, math.cos(a), math.sin(a), segs, idx, limit, limit)
        assert got == (t < limit)
        n_true += got
    assert 50 < n_true < 250


def _oblique_room() -> np.ndarray:
    room = np.array([[0.0, 0.0], [4.0, -0.6], [5.2, 1.8], [3.1, 3.9], [1.0, 3.2], [-0.8, 1.5]])
    segs = np.concatenate([room, np.roll(room, -1, axis=0)], axis=1)
    return np.ascontiguousarray(np.concatenate([segs, [[2.0, 1.0, 2.6, 1.9]]]))


@pytest.mark.parametrize("range_max", [3.0, 1.2])
def test_scan_echoes_equal_every_path_traced_bit_for_bit(range_max):
    """A 72-beam scan (144 traced sub-rays: the span fan, second legs nearest mirror first and only as far
    as the cone's best echo) in a room of oblique walls and short free-standing ones, among robots, reads
    bit for bit what tracing every sub-ray's two legs against every wall and robot reads."""
    cfg = SonarConfig(range_max=range_max)
    ring = SonarRing(cfg)
    rng = np.random.default_rng(13)
    ends = rng.uniform([0.3, 0.3], [3.5, 2.8], (40, 2))  # 40 short free-standing walls: >= 16 near walls
    turn = rng.uniform(-math.pi, math.pi, 40)
    sticks = np.column_stack([ends, ends + 0.2 * np.column_stack([np.cos(turn), np.sin(turn)])])
    walls = _walls(np.ascontiguousarray(np.concatenate([_oblique_room(), sticks])))
    offsets = _subray_offsets(cfg.cone_deg, 5)
    cos_min = math.cos(math.radians(cfg.incidence_max_deg)) - 1e-12
    xy = np.column_stack([rng.uniform(0.3, 3.5, 6), rng.uniform(0.3, 2.8, 6)])
    axes = np.ascontiguousarray(rng.uniform(-4, 4, (6, 1)) + ring.scan_angles[None, :])
    share = _share(axes, offsets)
    assert len(np.unique(share)) >= kern.FAN_SPANS_MIN  # the span fan's case
    ox, oy = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
    discs = kern.Discs(*rays.disc_planes(xy, 0.15, np.arange(6), 6))
    idx, cnt = rays.near_segments(ox, oy, walls.segments, cfg.range_max)
    assert (cnt >= kern.FAN_SPANS_WALLS).sum() >= 3  # the span fan's case for most origins
    got = np.empty(axes.shape)
    kern.sonar_echoes(ox, oy, axes, offsets, share, walls.kernel, idx, cnt, discs, _rules(cfg), got)
    for n in range(6):
        others = [tuple(p) for i, p in enumerate(xy) if i != n]
        want = reference.specular_echoes(ox[n], oy[n], axes[n], offsets, walls.segments, walls.kernel.lengths,
                                         others, 0.15 * 0.15, cfg.range_max, cos_min, _NUDGE)
        assert got[n].tobytes() == np.array(want).tobytes(), n
    assert ((got > 2.0 * range_max / 3.0) & np.isfinite(got)).sum() > 0  # two-leg echoes among them


def test_corner_echoes_of_an_even_fan_equal_each_beam_alone():
    """The corner echoes of a 72-beam scan (the beams near each corner's bearing picked by index) equal
    those of each beam cast alone (every beam tested) bit for bit; from (0.5, 0.5) in the square room
    the corner (0, 0) reads sqrt(0.5) m in exactly the beams whose 30-degree cone holds its bearing."""
    cfg = SonarConfig()
    ring = SonarRing(cfg)
    for segs, origins in ((SQUARE, np.array([[0.5, 0.5], [3.0, 1.2], [2.0, 3.7]])),
                          (_oblique_room(), np.array([[0.4, 0.5], [3.9, 1.1], [1.5, 2.6]]))):
        walls = _walls(np.ascontiguousarray(segs))
        ox, oy = np.ascontiguousarray(origins[:, 0]), np.ascontiguousarray(origins[:, 1])
        axes = np.ascontiguousarray(np.array([[0.3], [-2.0], [3.1]]) + ring.scan_angles[None, :])
        assert all(kern.even_fan(a, 2 * math.pi / 72) for a in axes)
        discs = kern.Discs(*rays.disc_planes(np.zeros((0, 2)), 0.1, np.full(3, -1), 3))
        idx, cnt = rays.near_segments(ox, oy, walls.segments, cfg.range_max)
        got = np.full(axes.shape, np.inf)
        kern.sonar_corner_echoes(ox, oy, axes, walls.kernel, idx, cnt, discs, _rules(cfg), got)
        alone = np.full(axes.shape, np.inf)
        for b in range(72):
            col = np.full((3, 1), np.inf)
            kern.sonar_corner_echoes(ox, oy, np.ascontiguousarray(axes[:, b:b + 1]), walls.kernel, idx, cnt, discs,
                                     _rules(cfg), col)
            alone[:, b] = col[:, 0]
        assert got.tobytes() == alone.tobytes() and np.isfinite(got).sum() >= 6
    # the square room, origin (0.5, 0.5), heading 0.3: the corner (0, 0) at bearing -135 degrees
    got0 = np.full((1, 72), np.inf)
    axes0 = np.ascontiguousarray(0.3 + ring.scan_angles[None, :])
    walls = _walls(SQUARE)
    idx, cnt = rays.near_segments(np.array([0.5]), np.array([0.5]), walls.segments, cfg.range_max)
    kern.sonar_corner_echoes(np.array([0.5]), np.array([0.5]), axes0, walls.kernel, idx, cnt,
                             kern.Discs(*rays.disc_planes(np.zeros((0, 2)), 0.1, np.full(1, -1), 1)), _rules(cfg),
                             got0)
    bearing = math.atan2(-0.5, -0.5)
    inside = [b for b in range(72) if abs(math.remainder(bearing - axes0[0, b], 2 * math.pi)) <= math.radians(15)]
    assert len(inside) == 6 and np.flatnonzero(got0[0] == math.sqrt(0.5)).tolist() == inside
    assert not kern.even_fan(np.array([0.0, 0.1, 0.25]), 0.1)  # not evenly spaced: every beam is tested


def test_boxed_hits_equal_the_culled_hits():
    """The second legs' and sight lines' casts with the near walls' boxes tested in one pass: from (1, 1)
    along +x within 3.5 m the right wall (1) at 3 m, nothing within 2.5 m; random rays on random walls
    give :func:`segment_hit` (culled) and :func:`wall_before` bit for bit."""
    every = np.arange(4)
    boxes, meets = np.empty((4, 4)), np.empty(4, dtype=np.bool_)
    rk.near_boxes(SQUARE, every, boxes)
    assert boxes[:, 1].tolist() == [4.0, 4.0, 0.0, 4.0]
    assert rk.segment_hit_boxed(1.0, 1.0, 1.0, 0.0, SQUARE, every, boxes, meets, 3.5) == (3.0, 1, 4.0)
    assert rk.segment_hit_boxed(1.0, 1.0, 1.0, 0.0, SQUARE, every, boxes, meets, 2.5)[1] == -1
    rng = np.random.default_rng(21)
    segs = rng.uniform(0, 4, (40, 4))
    idx = np.sort(rng.choice(40, 25, replace=False))
    boxes, meets = np.empty((4, 40)), np.empty(40, dtype=np.bool_)
    rk.near_boxes(segs, idx, boxes)
    hits = 0
    for _ in range(400):
        x, y, a, reach = *rng.uniform(0, 4, 2), rng.uniform(-4, 4), rng.uniform(0.05, 3)
        dx, dy = math.cos(a), math.sin(a)
        want = rk.segment_hit(x, y, dx, dy, segs, idx, reach, True, False)
        assert rk.segment_hit_boxed(x, y, dx, dy, segs, idx, boxes, meets, reach) == want
        assert rk.wall_before_boxed(x, y, dx, dy, segs, idx, boxes, meets, reach, reach) == \
            rk.wall_before(x, y, dx, dy, segs, idx, reach, reach)
        hits += want[1] >= 0
    assert 100 < hits < 390
