"""References of :mod:`parcover_env.sensors.sonar_kernels`, plain Python and numpy:

* :func:`beams` (with :func:`nearest_echo`, :func:`corners`): a brute-force ring, every sub-ray
  against every wall and robot plus the concave corners, the rules of
  :func:`parcover_env.sensors.sonar.simulate_beams` without multipath (compared to ~1e-4 m);
* :func:`specular_echoes` and :func:`disc_echoes`: :func:`~parcover_env.sensors.sonar_kernels.sonar_echoes`
  with the kernel's float operations (both legs of every sub-ray, every wall and robot, no culling),
  compared bit for bit;
* :func:`crosstalk`: :func:`~parcover_env.sensors.sonar_ring_kernels.sonar_crosstalk`, every pair of robots;
* :func:`noise`: :func:`~parcover_env.sensors.sonar_ring_kernels.ring_noise` as numpy formulas.
"""

from __future__ import annotations

import math

import numpy as np

from parcover_env.config import SonarConfig


def nearest_echo(o, ang, segs, discs, radius, cos_min):
    """Brute force: nearest hit, whether it echoes (specular), plain Python loops."""
    d = (math.cos(ang), math.sin(ang))
    best, echo = math.inf, False
    for x1, y1, x2, y2 in segs:
        ex, ey = x2 - x1, y2 - y1
        den = d[0] * ey - d[1] * ex
        if abs(den) < 1e-12:
            continue
        wx, wy = x1 - o[0], y1 - o[1]
        t = (wx * ey - wy * ex) / den
        u = (wx * d[1] - wy * d[0]) / den
        if t >= 0 and -1e-12 <= u <= 1 + 1e-12 and t < best:
            best, echo = t, abs(den) / math.hypot(ex, ey) >= cos_min - 1e-12
    for c in discs:
        ox, oy = o[0] - c[0], o[1] - c[1]
        b = ox * d[0] + oy * d[1]
        cc = ox * ox + oy * oy - radius * radius
        if b * b - cc < 0:
            continue
        t = 0.0 if cc <= 0 else -b - math.sqrt(b * b - cc)
        if t >= 0 and t < best:
            best, echo = t, True
    return best, echo


def corners(segs):
    out = []
    for i, s in enumerate(segs):
        for j, q in enumerate(segs):
            if j <= i:
                continue
            for a, a_other in ((s[:2], s[2:]), (s[2:], s[:2])):
                for b, b_other in ((q[:2], q[2:]), (q[2:], q[:2])):
                    if np.allclose(a, b, atol=1e-9):
                        out.append((a, a_other - a, b_other - a))
    return out


def beams(cfg: SonarConfig, origin, axes, segs, discs, radius, n_sub=5):
    cos_min = math.cos(math.radians(cfg.incidence_max_deg))
    spec = cfg.model == "specular"
    offs = np.linspace(-0.5, 0.5, n_sub) * math.radians(cfg.cone_deg) if spec else [0.0]
    vertices = corners(segs) if spec else []
    out = []
    for ax in axes:
        best = math.inf
        for off in offs:
            t, echo = nearest_echo(origin, ax + off, segs, discs, radius, cos_min if spec else -1.0)
            if echo:
                best = min(best, t)
        for c, u1, u2 in vertices:
            v = np.asarray(origin) - c
            cr = lambda p, q: p[0] * q[1] - p[1] * q[0]  # noqa: E731
            s = cr(u1, u2)
            if abs(s) < 1e-9 or not (cr(u1, v) * s > 0 and cr(v, u2) * s > 0):
                continue
            dist = float(np.linalg.norm(v))
            bearing = math.atan2(-v[1], -v[0])
            if dist > cfg.range_max or abs(math.remainder(bearing - ax, 2 * math.pi)) > math.radians(
                    cfg.cone_deg) / 2:
                continue
            t, _ = nearest_echo(origin, bearing, segs, discs, radius, -1.0)
            if t >= dist * (1 - 1e-7) - 1e-9:
                best = min(best, dist)
        out.append(min(best, cfg.range_max))
    return np.array(out)


def noise(cfg, ideal, heard, rng):
    """The ring's noise as numpy formulas (the reference of the compiled kernel): cross-talk, drop
    or clip below range_min, Gaussian noise on echoes, quantization, clamping, garbage."""
    r = np.asarray(ideal, dtype=float)
    if heard is not None:
        r = np.where(rng.random(r.shape) < cfg.crosstalk_prob, np.minimum(r, heard), r)
    if cfg.below_min == "drop":
        r = np.where(r < cfg.range_min, cfg.range_max, r)
    echo = r < cfg.range_max
    if rng is not None and (cfg.noise_std > 0 or cfg.noise_rel > 0):
        r = np.where(echo, r + (cfg.noise_std + cfg.noise_rel * r) * rng.standard_normal(r.shape), r)
    if cfg.quantization > 0:
        r = np.where(echo, np.round(r / cfg.quantization) * cfg.quantization, r)
    r = np.clip(r, cfg.range_min, cfg.range_max)
    if rng is not None and cfg.garbage_rate > 0:
        bad = rng.random(r.shape) < cfg.garbage_rate
        r = np.where(bad, rng.uniform(cfg.range_min, cfg.range_max, r.shape), r)
    return r


def subray(axis: float, offset: float) -> tuple[float, float]:
    """A sub-ray's unit direction: the beam axis's ``(cos, sin)`` rotated by the offset (the kernels' float
    operations)."""
    ax, ay, co, so = math.cos(axis), math.sin(axis), math.cos(offset), math.sin(offset)
    return ax * co - ay * so, ay * co + ax * so


def fan(axes, offsets) -> list[list[tuple[float, float]]]:
    """The sub-ray directions of beams ``axes`` (one origin): sub-ray ``j`` of beam ``b`` is the first
    pair ``(b', j')`` in that order whose angle is within 1e-9 rad of ``axes[b] + offsets[j]`` (the
    same ray of overlapping cones), pointing as :func:`subray` of ``axes[b'], offsets[j']``."""
    pairs = [(axis, off) for axis in axes for off in offsets]
    dirs = []
    for axis, off in pairs:
        first = next(p for p in pairs if abs(math.remainder(p[0] + p[1] - (axis + off), 2 * math.pi)) < 1e-9)
        dirs.append(subray(*first))
    return [dirs[b * len(offsets):(b + 1) * len(offsets)] for b in range(len(axes))]


def disc_echoes(origins, axes, offsets, centres, r, owner, rmax):
    """Nearest disc echo of every beam (no walls): each sub-ray against every disc with the
    kernels' float operations in plain Python (:func:`disc_t`; the reference of the compiled cone
    and range culls)."""
    out = np.full(axes.shape, math.inf)
    for n, (x0, y0) in enumerate(origins):
        others = [c for d, c in enumerate(centres) if d != owner[n]]
        for b, dirs in enumerate(fan(axes[n], offsets)):
            for dx, dy in dirs:
                t = disc_t(x0, y0, dx, dy, others, r * r)
                if t <= rmax:
                    out[n, b] = min(out[n, b], t)
    return np.minimum(out, rmax)


def first_hit(x0, y0, dx, dy, segs):
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


def disc_t(x0, y0, dx, dy, discs, r2):
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


def specular_echoes(x0, y0, axes, offsets, segs, lengths, discs, r2, rmax, cos_min, nudge):
    """Every sub-ray of every beam, both legs, every wall and disc, no culling (plain Python): the
    nearest echo per beam (inf if none), the specular multipath rule of ``sonar_echoes``."""
    out = []
    for dirs in fan(axes, offsets):
        best = math.inf
        for dx, dy in dirs:
            t1, i1, den = first_hit(x0, y0, dx, dy, segs)
            td = disc_t(x0, y0, dx, dy, discs, r2)
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
                t2w, i2, den2 = first_hit(px, py, d2x, d2y, segs)
                if not (i2 >= 0 and t2w <= reach):
                    t2w, i2 = math.inf, -1
                wall2 = t2w if i2 >= 0 and abs(den2) / max(lengths[i2], 1e-9) >= cos_min else math.inf
                td2 = disc_t(px, py, d2x, d2y, discs, r2)
                t2 = (td2 if td2 < t2w else wall2) + nudge
                echo = t1 + t2 if t2 <= rmax - t1 else math.inf
            best = min(best, echo)
        out.append(best)
    return out


def crosstalk(cfg, poses, beams, segs):
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


def wall_set(segs: np.ndarray) -> tuple[np.ndarray, ...]:
    """:func:`~parcover_env.sensors.sonar_kernels.wall_set` one segment and one vertex at a time, as it
    was written before it was vectorized: ``(lengths, points, u1, u2, owned)``. Each end rounded as
    ``round(np.float64, 9)``; a vertex shared by exactly two segments whose unit directions
    ``u / np.linalg.norm(u)`` are not collinear is a corner, listed at the first of its two walls."""
    n = len(segs)
    lengths = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    ends: dict = {}
    for i, (x1, y1, x2, y2) in enumerate(segs):
        a, b = (round(x1, 9), round(y1, 9)), (round(x2, 9), round(y2, 9))
        if a == b:
            continue
        ends.setdefault(a, []).append((np.array(b), i))
        ends.setdefault(b, []).append((np.array(a), i))
    pts, u1s, u2s = [], [], []
    owned = np.full((n, 2), -1, dtype=np.int64)
    for v, others in ends.items():
        if len(others) != 2:
            continue
        vv = np.array(v)
        (end1, i1), (end2, i2) = others
        u1, u2 = end1 - vv, end2 - vv
        u1, u2 = u1 / np.linalg.norm(u1), u2 / np.linalg.norm(u2)
        if abs(u1[0] * u2[1] - u1[1] * u2[0]) < 1e-9:
            continue
        first = min(i1, i2)
        owned[first, int(owned[first, 0] >= 0)] = len(pts)
        pts.append(vv)
        u1s.append(u1)
        u2s.append(u2)
    corners = (np.array(pts), np.array(u1s), np.array(u2s)) if pts else (np.zeros((0, 2)),) * 3
    return (lengths, *corners, owned)
