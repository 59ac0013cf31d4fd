"""Seeded search for a seed B Fig. 4 geometry: a room with a triangular obstacle whose visibility
sectors count about 65 original / exactly 7 after merge rule #1 / exactly 3 after rule #2 (unlimited
range), as ``parcover sectors SCENARIO --rule R --range inf`` counts them.

Room family: a T-shaped room (the room of Fig. 3; random bar and stem sizes) whose walls may be bent
inwards. A bend is a wall corner that is *not* a feature (free space is reflex there, a sonar sees
no local maximum) but it hides features from parts of the room, so it adds visibility-boundary
lines (original sectors) while the features, and so rules #1 / #2, barely change. Obstacle: one
triangle (not a needle: ``--min-tri-area``, ``--min-tri-angle``) at least ``--clearance`` from
the walls (the robot passes on every side). Kept: 7 / 3 exactly, not 7 features (the paper: after
rule #1 "the number of sectors is not the same as the number of features"), no relaxed sector
smaller than ``--min-area`` (no slivers), the robot's free space (eroded by its radius) in one
piece. Prints one JSON line per geometry kept, the best (original count nearest ``--target``) last.
A random stage (``--n``) then hill climbing (``--refine``, or from ``--start``):

    PYTHONPATH=. python tools/fig4_search.py --seed 0 --n 400
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
from shapely.geometry import Polygon

from parcover_env.config import MapConfig
from parcover_env.localization.sonar.features import map_features
from parcover_env.localization.sonar.sectors import compute_sectors
from parcover_env.world.map_model import MapModel


def t_room(rng: np.random.Generator) -> list[list[float]]:
    """A T: bar ``w x hb`` on top of a stem ``ws x hs`` (random sizes, stem anywhere along the bar)."""
    w, hb = rng.uniform(3.5, 6.0), rng.uniform(1.4, 2.4)
    ws, hs = rng.uniform(1.2, 2.2), rng.uniform(1.6, 3.0)
    x0 = rng.uniform(0.6, w - ws - 0.6)
    return [[x0, 0.0], [x0 + ws, 0.0], [x0 + ws, hs], [w, hs], [w, hs + hb], [0.0, hs + hb],
            [0.0, hs], [x0, hs]]


def bend_walls(ring: list[list[float]], rng: np.random.Generator, n_bends: int,
               depth: tuple[float, float]) -> list[list[float]]:
    """Insert ``n_bends`` wall corners, each pushed inwards from a point of a random wall."""
    pts = [np.asarray(p, float) for p in ring]
    area2 = sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(pts, pts[1:] + pts[:1], strict=True))
    for _ in range(n_bends):
        k = int(rng.integers(len(pts)))
        a, b = pts[k], pts[(k + 1) % len(pts)]
        e = b - a
        if np.hypot(*e) < 1.2:
            continue
        left = np.array([-e[1], e[0]]) / np.hypot(*e)  # inwards for a counter-clockwise ring
        inward = left if area2 > 0 else -left
        p = a + rng.uniform(0.3, 0.7) * e + rng.uniform(*depth) * inward
        pts.insert(k + 1, p)
    return [[float(x), float(y)] for x, y in pts]


def triangle(free: Polygon, rng: np.random.Generator, clearance: float) -> list[list[float]] | None:
    x0, y0, x1, y1 = free.bounds
    for _ in range(200):
        c = rng.uniform([x0, y0], [x1, y1])
        size = rng.uniform(0.4, 1.4)
        ang = rng.uniform(0, 2 * math.pi) + np.sort(rng.uniform(0, 2 * math.pi, 3))
        tri = c + size * np.stack([np.cos(ang), np.sin(ang)], axis=1) * rng.uniform(0.5, 1.0, (3, 1))
        poly = Polygon(tri)
        if not poly.is_valid or poly.area < 0.08:
            continue
        if free.contains(poly) and free.exterior.distance(poly) >= clearance:
            return [[round(float(x), 2), round(float(y), 2)] for x, y in tri]
    return None


def fat_triangle(tri, min_area: float, min_angle_deg: float) -> bool:
    """A proper triangle, not a needle: area and smallest interior angle at least the given ones."""
    t = np.asarray(tri, dtype=float)
    if Polygon(t).area < min_area:
        return False
    for i in range(3):
        u, v = t[(i + 1) % 3] - t[i], t[(i + 2) % 3] - t[i]
        cos = u @ v / (np.hypot(*u) * np.hypot(*v))
        if math.degrees(math.acos(np.clip(cos, -1.0, 1.0))) < min_angle_deg:
            return False
    return True


def evaluate(boundary, tri, radius: float, min_area: float) -> dict | None:
    try:
        cfg = MapConfig(size=(10.0, 10.0), boundary=tuple(map(tuple, boundary)), obstacles=(tuple(map(tuple, tri)),))
        m = MapModel.from_config(cfg)
    except Exception:  # noqa: BLE001 - an invalid random polygon is just skipped
        return None
    eroded = m.free.buffer(-radius)
    if eroded.geom_type != "Polygon":
        return None
    feats = map_features(m)
    n0 = len(compute_sectors(m, math.inf, 0, feats))
    s1 = compute_sectors(m, math.inf, 1, feats)
    if len(s1) != 7:
        return {"n0": n0, "n1": len(s1)}
    s2 = compute_sectors(m, math.inf, 2, feats)
    small = min(s.polygon.area for s in s1 + s2)
    return {"n0": n0, "n1": 7, "n2": len(s2), "n_features": len(feats), "min_relaxed_area": round(small, 3),
            "ok": len(s2) == 3 and small >= min_area and len(feats) != 7}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--n", type=int, default=200, help="geometries to try")
    ap.add_argument("--bends", type=int, nargs=2, default=[0, 4], help="min and max wall bends")
    ap.add_argument("--depth", type=float, nargs=2, default=[0.1, 0.6], help="bend depth range (m)")
    ap.add_argument("--clearance", type=float, default=0.45, help="triangle to wall (m)")
    ap.add_argument("--radius", type=float, default=0.165, help="robot radius (m)")
    ap.add_argument("--min-area", type=float, default=0.1, help="smallest relaxed sector (m^2)")
    ap.add_argument("--min-tri-area", type=float, default=0.1, help="smallest triangle (m^2)")
    ap.add_argument("--min-tri-angle", type=float, default=15.0, help="smallest triangle angle (deg)")
    ap.add_argument("--target", type=int, default=65)
    ap.add_argument("--refine", type=int, default=0, help="hill-climbing steps from the best geometry")
    ap.add_argument("--step", type=float, default=0.08, help="hill-climbing vertex move (m, std)")
    ap.add_argument("--p-bend", type=float, default=0.0, help="hill climbing: chance a step adds a wall bend")
    ap.add_argument("--start", default=None, help="a JSON line printed by a previous run: refine from it")
    ap.add_argument("--verbose", action="store_true", help="print every evaluated geometry to stderr")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    best = json.loads(Path(args.start).read_text().strip().splitlines()[-1]) if args.start else None
    best = best.get("best", best) if best else None
    for trial in range(args.n if best is None else 0):
        ring = t_room(rng)
        ring = bend_walls(ring, rng, int(rng.integers(args.bends[0], args.bends[1] + 1)), tuple(args.depth))
        ring = [[round(x, 2), round(y, 2)] for x, y in ring]
        room = Polygon(ring)
        if not room.is_valid:
            continue
        tri = triangle(room, rng, args.clearance)
        if tri is None or not fat_triangle(tri, args.min_tri_area, args.min_tri_angle):
            continue
        res = evaluate(ring, tri, args.radius, args.min_area)
        if args.verbose and res:
            print(trial, res, file=sys.stderr)
        if not res or not res.get("ok"):
            continue
        row = {"trial": trial, **res, "boundary": ring, "triangle": tri}
        print(json.dumps(row), flush=True)
        if best is None or abs(res["n0"] - args.target) < abs(best["n0"] - args.target):
            best = row
    if best is not None and args.refine:
        best = refine(best, rng, args)
    print(json.dumps({"best": best}))


def refine(best: dict, rng: np.random.Generator, args) -> dict:
    """Hill climbing: move one vertex (wall or triangle) by ``--step`` metres (normal) or, with chance
    ``--p-bend``, add a wall bend; keep the step when the geometry stays admissible and the original
    count gets no farther from ``--target``."""
    for it in range(args.refine):
        ring = [list(p) for p in best["boundary"]]
        tri = [list(p) for p in best["triangle"]]
        if rng.random() < args.p_bend:  # a new wall bend
            ring = [[round(x, 2), round(y, 2)] for x, y in bend_walls(ring, rng, 1, tuple(args.depth))]
        else:
            k = int(rng.integers(len(ring) + 3))
            tgt = ring if k < len(ring) else tri
            k = k if k < len(ring) else k - len(ring)
            tgt[k] = [round(float(v + rng.normal(0, args.step)), 2) for v in tgt[k]]
        room = Polygon(ring)
        t = Polygon(tri)
        if not (room.is_valid and t.is_valid and room.contains(t) and room.exterior.distance(t) >= args.clearance
                and fat_triangle(tri, args.min_tri_area, args.min_tri_angle)):
            continue
        res = evaluate(ring, tri, args.radius, args.min_area)
        if not res or not res.get("ok"):
            continue
        if abs(res["n0"] - args.target) <= abs(best["n0"] - args.target):
            best = {"trial": f"refine {it}", **res, "boundary": ring, "triangle": tri}
            print(json.dumps(best), flush=True)
    return best


if __name__ == "__main__":
    main()
