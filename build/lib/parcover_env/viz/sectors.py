"""Drawing of visibility sectors (seed B Figs. 3-4) as an RGB image with cv2."""

from __future__ import annotations

import colorsys

import cv2
import numpy as np

from parcover_env.localization.sonar.features import MapFeature
from parcover_env.localization.sonar.sectors import Sector

__all__ = ["draw_sectors"]


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
