"""The sonar's compiled loops against plain-Python references that trace every sub-ray of every beam
(both legs, every wall and robot, no culling) and every pair of robots for cross-talk: bit for bit,
with the kernels' float operations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import SonarConfig
from parcover_env.sensors.sonar import SonarRing


def _oblique_room() -> np.ndarray:
    """Walls ``(S, 4)`` of a hexagonal room of oblique walls with a free-standing oblique wall inside."""
    room = np.array([[0.0, 0.0], [4.0, -0.6], [5.2, 1.8], [3.1, 3.9], [1.0, 3.2], [-0.8, 1.5]])
    segs = np.concatenate([room, np.roll(room, -1, axis=0)], axis=1)
    return np.ascontiguousarray(np.concatenate([segs, [[2.0, 1.0, 2.6, 1.9]]]))


def _subray(axis: float, offset: float) -> tuple[float, float]:
    """A sub-ray's unit direction: the beam axis's ``(cos, sin)`` rotated by the offset (the kernels' float
    operations)."""
    ax, ay, co, so = math.cos(axis), math.sin(axis), math.cos(offset), math.sin(offset)
    return ax * co - ay * so, ay * co + ax * so


def _fan(axes, offsets) -> list[list[tuple[float, float]]]:
    """The sub-ray directions of beams ``axes`` (one origin): sub-ray ``j`` of beam ``b`` is the first
    pair ``(b', j')`` in that order whose angle is within 1e-9 rad of ``axes[b] + offsets[j]`` (the
    same ray of overlapping cones), pointing as :func:`_subray` of ``axes[b'], offsets[j']``."""
    pairs = [(axis, off) for axis in axes for off in offsets]
    dirs = []
    for axis, off in pairs:
        first = next(p for p in pairs if abs(math.remainder(p[0] + p[1] - (axis + off), 2 * math.pi)) < 1e-9)
        dirs.append(_subray(*first))
    return [dirs[b * len(offsets):(b + 1) * len(offsets)] for b in range(len(axes))]


def _disc_echo_reference(origins, axes, offsets, centres, r, owner, rmax):
    """Nearest disc echo of every beam (no walls): each sub-ray against every disc with the
    kernels' float operations in plain Python (:func:`_disc_t`; the reference of the compiled cone
    and range culls)."""
    out = np.full(axes.shape, math.inf)
    for n, (x0, y0) in enumerate(origins):
        others = [c for d, c in enumerate(centres) if d != owner[n]]
        for b, dirs in enumerate(_fan(axes[n], offsets)):
            for dx, dy in dirs:
                t = _disc_t(x0, y0, dx, dy, others, r * r)
                if t <= rmax:
                    out[n, b] = min(out[n, b], t)
    return np.minimum(out, rmax)


def test_disc_culls_change_no_reading():
    """The sonar kernel tests only the discs within range of a robot and inside a beam's cone: bit
    for bit the readings of every sub-ray against every disc, on random crowds and on discs just
    inside and just outside a cone's edge ray and the range."""
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
        want = _disc_echo_reference(xy, axes, offsets, xy, 0.12, np.arange(12), cfg.range_max)
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
        want = _disc_echo_reference(np.zeros((1, 2)), axes, offsets, centres, r, [0], rmax)
        assert got[0, 0] == want[0, 0], c
    hits = [simulate_beams(cfg, np.zeros((1, 2)), axes, none, np.array([[0.0, 0.0], c]), r, np.array([0]))[0, 0]
            for c in cases]
    assert [h < rmax for h in hits] == [True, False, True, False, True, False, True]
    assert hits[-1] == 0.0  # inside a disc: an echo at once


def _first_hit(x0, y0, dx, dy, segs):
    """Nearest wall hit of a ray in plain Python floats, the kernels' formulas: ``(t, index, d x e)``."""
    best, bi, bden = math.inf, -1, 0.0
    for s, (ax, ay, sx, sy) in enumerate(segs):
        ex, ey = sx - ax, sy - ay
        den = dx * ey - dy * ex
        if not abs(den) > 1e-12:
            continue
        wx, wy = ax - x0, ay - y0
        t = (wx * ey - wy * ex) / den
        u = (wx * dy - wy * dx) / den
        if t >= 0.0 and -1e-12 <= u <= 1.0 + 1e-12 and t < best:
            best, bi, bden = t, s, den
    return best, bi, bden


def _disc_t(x0, y0, dx, dy, discs, r2):
    best = math.inf
    for cx, cy in discs:
        ocx, ocy = x0 - cx, y0 - cy
        c = (ocx * ocx + ocy * ocy) - r2
        b = ocx * dx + ocy * dy
        if c > 0.0 and b >= 0.0:
            continue
        disc = b * b - c
        if not disc >= 0.0:
            continue
        t = 0.0 if c <= 0.0 else -b - math.sqrt(disc)
        if t >= 0.0:
            best = min(best, t)
    return best


def _specular_reference(x0, y0, axes, offsets, segs, lengths, discs, r2, rmax, cos_min, nudge):
    """Every sub-ray of every beam, both legs, every wall and disc, no culling (plain Python): the
    nearest echo per beam (inf if none), the specular multipath rule of ``sonar_echoes``."""
    out = []
    for dirs in _fan(axes, offsets):
        best = math.inf
        for dx, dy in dirs:
            t1, i1, den = _first_hit(x0, y0, dx, dy, segs)
            td = _disc_t(x0, y0, dx, dy, discs, r2)
            td = td if td <= rmax else math.inf
            if not (i1 >= 0 and t1 <= rmax):
                t1, i1 = math.inf, -1
            echo = math.inf
            if td < t1:
                echo = td
            elif i1 >= 0 and abs(den) / max(lengths[i1], 1e-9) >= cos_min:
                echo = t1
            elif i1 >= 0:  # the mirrored second leg
                ax, ay, sx, sy = segs[i1]
                ex, ey = sx - ax, sy - ay
                norm = math.sqrt(ex * ex + ey * ey)
                nx, ny = -ey / norm, ex / norm
                f = 2.0 * (dx * nx + dy * ny)
                d2x, d2y = dx - f * nx, dy - f * ny
                px, py = (x0 + dx * t1) + d2x * nudge, (y0 + dy * t1) + d2y * nudge
                reach = rmax - t1
                t2w, i2, den2 = _first_hit(px, py, d2x, d2y, segs)
                if not (i2 >= 0 and t2w <= reach):
                    t2w, i2 = math.inf, -1
                wall2 = t2w if i2 >= 0 and abs(den2) / max(lengths[i2], 1e-9) >= cos_min else math.inf
                td2 = _disc_t(px, py, d2x, d2y, discs, r2)
                t2 = (td2 if td2 < t2w else wall2) + nudge
                echo = t1 + t2 if t2 <= rmax - t1 else math.inf
            best = min(best, echo)
        out.append(best)
    return out


def test_specular_multipath_echoes_equal_every_path_traced_bit_for_bit():
    """The compiled cone (near-wall lists, box and best-echo culls, direct echoes before mirrored
    legs, disc culls) reads bit for bit what tracing every sub-ray's two legs against every wall and
    robot reads, in a room of oblique walls with a crowd of robots."""
    from parcover_env.geometry import rays
    from parcover_env.sensors import sonar_kernels as kern
    from parcover_env.sensors.sonar import _NUDGE, _rules, _share, _subray_offsets, _walls

    cfg = SonarConfig()
    ring = SonarRing(cfg)
    walls = _walls(_oblique_room())
    offsets = _subray_offsets(cfg.cone_deg, 5)
    cos_min = math.cos(math.radians(cfg.incidence_max_deg)) - 1e-12
    rng = np.random.default_rng(12)
    n_mirrored = 0
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
            want = _specular_reference(ox[n], oy[n], axes[n], offsets, walls.segments, walls.kernel.lengths, others,
                                       0.15 * 0.15, cfg.range_max, cos_min, _NUDGE)
            assert got[n].tobytes() == np.array(want).tobytes(), n
        n_mirrored += int(((got > 2.0) & np.isfinite(got)).sum())
    assert n_mirrored > 0  # some readings are two-leg paths


def _crosstalk_reference(cfg, poses, beams, segs):
    """Cross-talk ``(N, B)`` in plain Python, every pair and beam, no pre-test: beam ``b`` of ``i`` hears
    the nearest ``j`` whose bearing is within the half cone of that beam's axis, with a beam of ``j``
    pointing back at ``i``, ``0 < d / 2 <= range_max`` and no wall strictly between them."""
    from parcover_env.sensors.sonar import _half_cone

    half, rmax = _half_cone(cfg), cfg.range_max

    def in_cone(a):
        return abs(math.pi - ((math.pi - a) % (2 * math.pi))) <= half

    def blocked(x0, y0, dx, dy):
        for x1, y1, x2, y2 in segs:
            ex, ey = x2 - x1, y2 - y1
            den = dx * ey - dy * ex
            if abs(den) > 1e-12:
                wx, wy = x1 - x0, y1 - y0
                t, u = (wx * ey - wy * ex) / den, (wx * dy - wy * dx) / den
                if 0 < t < 1 and -1e-12 <= u <= 1 + 1e-12:
                    return True
        return False

    out = np.full((len(poses), len(beams)), math.inf)
    for i, (xi, yi, ti) in enumerate(poses):
        for j, (xj, yj, tj) in enumerate(poses):
            dx, dy = xj - xi, yj - yi
            d = float(np.hypot(dx, dy))  # libm's hypot, as compiled code calls it (not Python's own)
            if i == j or not (d > 0 and d / 2 <= rmax) or blocked(xi, yi, dx, dy):
                continue
            bearing = math.atan2(dy, dx)
            if not any(in_cone(bearing + math.pi - tj - c) for c in beams):
                continue
            for b, beam in enumerate(beams):
                if in_cone(bearing - ti - beam):
                    out[i, b] = min(out[i, b], d / 2)
    return out


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
                    assert np.array_equal(got, _crosstalk_reference(cfg, poses, beams, none)), (eps, sign, off)
                    inside += np.isfinite(got[0, 1])
                    outside += np.isinf(got[0, 1])
    assert inside > 4 and outside > 4
    walls = _oblique_room()
    rng = np.random.default_rng(3)
    for _ in range(5):
        poses = np.column_stack([rng.uniform(0, 4, (10, 2)), rng.uniform(-4, 4, 10)])
        got = crosstalk(cfg, poses, beams, walls)
        assert np.array_equal(got, _crosstalk_reference(cfg, poses, beams, walls)) and np.isfinite(got).any()


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
