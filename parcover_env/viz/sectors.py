"""Drawing of visibility sectors (Kim, Pearce & Amato Figs. 3-4) as an RGB image with cv2."""

from __future__ import annotations

import colorsys

import cv2
import numpy as np
import shapely

from parcover_env.errors import ArgumentError
from parcover_env.localization.sonar.features import MapFeature
from parcover_env.localization.sonar.sectors import Sector

__all__ = ["draw_sectors", "rearrangement_figure"]


def _colour(i: int) -> tuple[int, int, int]:
    r, g, b = colorsys.hsv_to_rgb((i * 0.618034) % 1.0, 0.45, 0.95)
    return int(255 * r), int(255 * g), int(255 * b)


def draw_sectors(map_model, sectors: list[Sector], features: list[MapFeature],
                 px_per_m: float = 100.0, margin_px: int = 20) -> np.ndarray:
    """RGB uint8 image: sectors filled in distinct colours and numbered (grey), walls in black,
    features as red dots numbered in red. World y points up in the image."""
    if px_per_m <= 0:
        raise ValueError(f"px_per_m must be > 0, got {px_per_m}")
    x0, y0, x1, y1 = map_model.bounds
    w = int(np.ceil((x1 - x0) * px_per_m)) + 2 * margin_px
    h = int(np.ceil((y1 - y0) * px_per_m)) + 2 * margin_px
    if w * h > 50_000_000:
        raise ValueError(f"image of {w}x{h} px is too large; lower px_per_m")
    img = np.full((h, w, 3), 255, dtype=np.uint8)

    def px(coords) -> np.ndarray:
        c = np.asarray(coords, dtype=float)
        return np.stack([margin_px + (c[:, 0] - x0) * px_per_m,
                         h - margin_px - (c[:, 1] - y0) * px_per_m], axis=1).round().astype(np.int32)

    def polys(geom):
        return [g for g in getattr(geom, "geoms", [geom]) if g.geom_type == "Polygon" and not g.is_empty]

    for i, s in enumerate(sectors):
        for poly in polys(s.polygon):
            rings = [px(poly.exterior.coords)] + [px(r.coords) for r in poly.interiors]
            cv2.fillPoly(img, rings, _colour(i), lineType=cv2.LINE_AA)
    for s in sectors:
        for poly in polys(s.polygon):
            cv2.polylines(img, [px(poly.exterior.coords)], True, (110, 110, 110), 1, cv2.LINE_AA)
    for poly in polys(map_model.free):
        for ring in [poly.exterior, *poly.interiors]:
            cv2.polylines(img, [px(ring.coords)], True, (0, 0, 0), 3, cv2.LINE_AA)
    font = cv2.FONT_HERSHEY_SIMPLEX
    for i, s in enumerate(sectors):
        q = px(np.array(s.polygon.representative_point().coords))[0]
        cv2.putText(img, f"S{i}", (int(q[0]) - 10, int(q[1]) + 5), font, 0.45, (60, 60, 60), 1, cv2.LINE_AA)
    for f in features:
        q = px(f.point[None, :])[0]
        cv2.circle(img, (int(q[0]), int(q[1])), 6, (220, 0, 0), -1, cv2.LINE_AA)
        inward = f.normals.sum(axis=0)
        inward = inward / max(np.linalg.norm(inward), 1e-9)
        t = px((f.point + inward * 18 / px_per_m)[None, :])[0]
        cv2.putText(img, str(f.index), (int(t[0]) - 5, int(t[1]) + 5), font, 0.5, (200, 0, 0), 1, cv2.LINE_AA)
    return img


def rearrangement_figure(scenario, px_per_m: float = 70.0, node_step: float = 0.05,
                         horizon: float = 7.0) -> tuple[np.ndarray, dict]:
    """Kim, Pearce & Amato Fig. 9(a) -> (b) on ``scenario`` (two robots): RGB image and the numbers drawn.

    (a) the first team subgoal after scan-angle optimization (eq. 1) within ``horizon`` metres of the
    start (the sonar navigator's default: ellipse limit 0.35 m / growth 0.05 m per m) over the robots' plan paths,
    robot 1 one formation spacing behind robot 0 (hollow discs); (b) the subgoals after the bisector
    rearrangement of §4 (filled discs), the bisector (dashed) and each robot's line of sight to the
    feature, red where the other robot blocks it, green where clear. Relaxed sectors (rule #2, the
    sonar's range) in the background.
    """
    import math

    from parcover_env.localization.sonar.sectors import compute_sectors
    from parcover_env.localization.sonar.subgoals import (
        bisector_rearrangement,
        densify,
        score_nodes,
        team_subgoal,
        unblocked_scan_angle,
    )
    from parcover_env.scenarios import mission_for

    mission = mission_for(scenario)
    if mission.n_robots < 2:
        raise ArgumentError(f"scenario {scenario.name!r} plans {mission.n_robots} robot(s); Fig. 9 needs two")
    known, sonar = mission.known_map, scenario.robot.sonar
    from parcover_env.localization.sonar.features import map_features

    feats = map_features(known)
    paths = [densify(p, node_step) for p in mission.plan.paths[:2]]
    step, inc = math.radians(sonar.scan_step_deg), math.radians(sonar.incidence_max_deg)
    inc = inc if sonar.model == "specular" else math.pi / 2
    scores = [score_nodes(p.xy, known, feats, sonar.range_min, sonar.range_max, step, inc) for p in paths]
    lags = np.array([0.0, scenario.formation.spacing])
    hi = min(min(p.s[-1] for p in paths), horizon + lags[1])
    sigma = team_subgoal(paths, [s.bias for s in scores], lags, lags[1], hi, node_step, math.radians(5.0))
    sig = sigma - lags
    before = np.array([p.point(s) for p, s in zip(paths, sig, strict=True)])
    k0 = paths[0].index(sig[0])
    fi = int(scores[0].feature[k0])
    if fi < 0:
        raise ValueError("no feature is available at the optimized subgoal")
    f = feats[fi]
    r = scenario.robot.radius
    free = known.free.buffer(-r)

    def in_free(pts):
        return np.array([free.contains(shapely.Point(*p)) for p in pts])

    res = bisector_rearrangement(before, paths, sig, f.point, 2 * r + 0.1, free=in_free)
    sectors = compute_sectors(known, sonar.range_max, rule=2, features=feats)
    img = draw_sectors(known, sectors, feats, px_per_m=px_per_m)
    img = (0.55 * img + 0.45 * 255).astype(np.uint8)  # faded background
    x0, y0, _, _ = known.bounds
    h, margin = img.shape[0], 20

    def px(p) -> tuple[int, int]:
        return int(round(margin + (p[0] - x0) * px_per_m)), int(round(h - margin - (p[1] - y0) * px_per_m))

    for p in paths:
        cv2.polylines(img, [np.array([px(q) for q in p.xy], np.int32)], False, (150, 150, 150), 1, cv2.LINE_AA)
    m, u = res.bisector
    a, b = m - 4.0 * u, m + 4.0 * u
    n_dash = 40
    for k in range(0, n_dash, 2):
        cv2.line(img, px(a + (b - a) * k / n_dash), px(a + (b - a) * (k + 1) / n_dash), (120, 0, 160), 2,
                 cv2.LINE_AA)

    def clearance(pts, i):
        d = f.point - pts[i]
        t = np.clip((pts[1 - i] - pts[i]) @ d / (d @ d), 0.0, 1.0)
        return float(np.hypot(*(pts[i] + t * d - pts[1 - i])))

    rad = max(2, int(round(r * px_per_m)))
    for pts, filled in ((before, False), (res.subgoals, True)):
        for i in range(2):
            ok = clearance(pts, i) > r
            colour = (0, 160, 0) if ok else (220, 0, 0)
            if filled:
                cv2.line(img, px(pts[i]), px(f.point), colour, 2, cv2.LINE_AA)
            cv2.circle(img, px(pts[i]), rad, (30, 30, 200), -1 if filled else 2, cv2.LINE_AA)
            cv2.putText(img, f"{'b' if filled else 'a'}{i}", (px(pts[i])[0] + rad, px(pts[i])[1] - rad),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.45, (30, 30, 30), 1, cv2.LINE_AA)
    cv2.putText(img, f"Fig. 9: (a) hollow -> (b) filled, feature {fi}", (10, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                (0, 0, 0), 1, cv2.LINE_AA)
    def worst_deg(pts) -> float:  # min_i A_i of §3.2 (deg)
        return math.degrees(min(unblocked_scan_angle(pts[i], f, pts[[1 - i]], r, sonar.range_max, inc,
                                                     math.radians(sonar.cone_deg) if sonar.model == "specular"
                                                     else 0.0) for i in range(2)))

    info = {"feature": fi, "min_scan_angle_deg_before": worst_deg(before),
            "min_scan_angle_deg_after": worst_deg(res.subgoals), "feature_point": f.point.tolist(),
            "before": before.tolist(),
            "after": res.subgoals.tolist(), "on_path": list(res.on_path),
            "sight_clear_before": [clearance(before, i) > r for i in range(2)],
            "sight_clear_after": [clearance(res.subgoals, i) > r for i in range(2)]}
    return img, info
