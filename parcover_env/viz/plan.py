"""Picture of a plan (like Min et al. Fig. 6b/6c): map, roadmap, robots' paths, TPs with robot counts,
numbered KPOIs, start, Kinect footprints, and a side panel with the Kinect tree. Drawn with cv2."""

from __future__ import annotations

import colorsys
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from parcover_env.planning.kinect_tree import KinectTree, kinect_footprints
from parcover_env.planning.plan import Plan
from parcover_env.planning.roadmap import edge_polyline
from parcover_env.viz.render import kpoi_label
from parcover_env.world.map_model import map_model

if TYPE_CHECKING:
    from parcover_env.config import Scenario

__all__ = ["draw_plan", "save_png", "robot_colors"]

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_WALL, _FREE, _ROADMAP, _TEXT = (60, 60, 60), (250, 250, 250), (190, 190, 190), (20, 20, 20)
_YELLOW = (240, 200, 0)


def robot_colors(n: int) -> list[tuple[int, int, int]]:
    """n well-separated RGB colours."""
    return [tuple(int(255 * c) for c in colorsys.hsv_to_rgb((i * 0.618034) % 1.0, 0.85, 0.85))
            for i in range(max(n, 1))]


def _rings(geom):
    for poly in getattr(geom, "geoms", [geom]):
        yield poly.exterior.coords, [i.coords for i in poly.interiors]


def draw_plan(scenario: Scenario, plan: Plan, kinect_tree: KinectTree | None = None,
              scale_px_per_m: float = 60.0, roadmap: bool = True) -> np.ndarray:
    """RGB image ``(H, W, 3) uint8`` of the plan on the scenario's known map."""
    from parcover_env.planning.scenario_plan import scenario_roadmap

    if not scale_px_per_m > 0:
        raise ValueError(f"scale_px_per_m must be > 0, got {scale_px_per_m}")
    model = map_model(scenario.map, include_unknown=False)
    x0, y0, x1, y1 = model.bounds
    s, m = float(scale_px_per_m), 30
    w_map, h_map = int(round((x1 - x0) * s)) + 2 * m, int(round((y1 - y0) * s)) + 2 * m + 24
    panel = 240 if kinect_tree is not None else 0
    img = np.full((h_map, w_map + panel, 3), 255, np.uint8)

    def px(pts) -> np.ndarray:
        p = np.asarray(pts, dtype=float).reshape(-1, 2)
        return np.stack([m + (p[:, 0] - x0) * s, h_map - m - (p[:, 1] - y0) * s], 1).round().astype(np.int32)

    cv2.rectangle(img, tuple(px([(x0, y0)])[0]), tuple(px([(x1, y1)])[0]), _WALL, -1)
    for ext, holes in _rings(model.free):
        cv2.fillPoly(img, [px(ext)], _FREE, cv2.LINE_AA)
        for h in holes:
            cv2.fillPoly(img, [px(h)], _WALL, cv2.LINE_AA)
    for poly in scenario.map.unknown_obstacles:  # not in the planner's map: outline only
        cv2.polylines(img, [px(poly)], True, (200, 80, 80), 1, cv2.LINE_AA)
    if scenario.kinects:
        overlay = img.copy()
        feet = kinect_footprints(scenario)
        kcols = robot_colors(len(feet) + 3)[3:]
        for fp, col in zip(feet.values(), kcols, strict=False):
            for ext, _ in _rings(fp):
                cv2.fillPoly(overlay, [px(ext)], col, cv2.LINE_AA)
        img[:] = cv2.addWeighted(overlay, 0.18, img, 0.82, 0)
        for (name, fp), col in zip(feet.items(), kcols, strict=False):
            for ext, _ in _rings(fp):
                cv2.polylines(img, [px(ext)], True, col, 1, cv2.LINE_AA)
            c = px([fp.centroid.coords[0]])[0] if not fp.is_empty else None
            if c is not None:
                cv2.putText(img, name, (int(c[0]) - 6, int(c[1]) + 6), _FONT, 0.7, col, 2, cv2.LINE_AA)
    if roadmap:
        g = scenario_roadmap(scenario).graph
        for u, v in g.edges:
            cv2.polylines(img, [px(edge_polyline(g, u, v))], False, _ROADMAP, 1, cv2.LINE_AA)
    cols = robot_colors(plan.r)
    for rp in reversed(plan.robots):  # leaders (low indices) drawn on top
        if len(rp.path) > 1:
            cv2.polylines(img, [px(rp.path)], False, cols[rp.index], 2, cv2.LINE_AA)
    owner = plan.kpoi_owner()
    half = max(4, int(0.12 * s))
    for i, k in enumerate(scenario.kpois):
        c = px([k])[0]
        col = cols[owner[i]] if 0 <= owner[i] < len(cols) else (0, 0, 0)
        cv2.rectangle(img, tuple(c - half), tuple(c + half), col, -1)
        cv2.rectangle(img, tuple(c - half), tuple(c + half), _TEXT, 1)
        cv2.putText(img, kpoi_label(i), (int(c[0]) + half + 2, int(c[1]) - half), _FONT, 0.4, _TEXT, 1, cv2.LINE_AA)
    for tp in plan.turning_points:
        c = px([tp.position])[0]
        tri = np.array([[c[0], c[1] - half - 3], [c[0] - half - 2, c[1] + half],
                        [c[0] + half + 2, c[1] + half]], np.int32)
        cv2.fillPoly(img, [tri], _YELLOW, cv2.LINE_AA)
        cv2.polylines(img, [tri], True, _TEXT, 1, cv2.LINE_AA)
        label = "/".join(str(b.n_robots) for b in tp.branches)
        org = (int(c[0]) + half + 3, int(c[1]) + half + 10)
        cv2.putText(img, label, org, _FONT, 0.4, _TEXT, 1, cv2.LINE_AA)
    sc = px([(scenario.start.x, scenario.start.y)])[0]
    cv2.circle(img, tuple(sc), half + 4, (255, 255, 255), -1, cv2.LINE_AA)
    cv2.circle(img, tuple(sc), half + 4, _TEXT, 2, cv2.LINE_AA)
    cv2.putText(img, "S", (int(sc[0]) - 5, int(sc[1]) + 5), _FONT, 0.45, _TEXT, 1, cv2.LINE_AA)
    header = f"{scenario.name}: r={plan.r}  c_max={plan.c_max:.2f} m  c_p={plan.c_p:.2f} m  ({plan.method})"
    cv2.putText(img, header, (m, 18), _FONT, 0.5, _TEXT, 1, cv2.LINE_AA)
    if kinect_tree is not None:
        _draw_kinect_panel(img, kinect_tree, w_map)
    return img


def _draw_kinect_panel(img: np.ndarray, kt: KinectTree, x_off: int) -> None:
    """Kinect tree (Fig. 6b): nodes by depth, links labelled with their crossing counts."""
    h = img.shape[0]
    cv2.rectangle(img, (x_off, 0), (img.shape[1] - 1, h - 1), (235, 235, 245), -1)
    cv2.putText(img, "Kinect tree", (x_off + 10, 20), _FONT, 0.55, _TEXT, 1, cv2.LINE_AA)
    depth: dict[str, int] = {}
    for name in kt.parent:
        d, cur = 0, name
        while kt.parent.get(cur) is not None:
            cur, d = kt.parent[cur], d + 1
        depth[name] = d
    levels: dict[int, list[str]] = {}
    for name in kt.parent:
        levels.setdefault(depth[name], []).append(name)
    n_lv = max(levels) + 1 if levels else 1
    pos = {}
    for d, names in levels.items():
        for j, name in enumerate(names):
            pos[name] = (x_off + int(240 * (j + 1) / (len(names) + 1)),
                         50 + int((h - 100) * d / max(n_lv - 1, 1)))
    for (a, b), count in kt.links.items():
        if a in pos and b in pos:
            tree_link = kt.parent.get(b) == a
            colour = (40, 40, 160) if tree_link else (150, 150, 150)
            cv2.line(img, pos[a], pos[b], colour, 2 if tree_link else 1, cv2.LINE_AA)
            mid = ((pos[a][0] + pos[b][0]) // 2 + 4, (pos[a][1] + pos[b][1]) // 2)
            cv2.putText(img, str(count), mid, _FONT, 0.45, (160, 30, 30), 1, cv2.LINE_AA)
    for name, p in pos.items():
        cv2.circle(img, p, 14, (255, 255, 255), -1, cv2.LINE_AA)
        cv2.circle(img, p, 14, _TEXT, 2 if name == kt.root else 1, cv2.LINE_AA)
        cv2.putText(img, name[:3], (p[0] - 9, p[1] + 5), _FONT, 0.45, _TEXT, 1, cv2.LINE_AA)
    if kt.unreached:
        cv2.putText(img, "unreached: " + ",".join(kt.unreached), (x_off + 8, h - 12), _FONT, 0.4, _TEXT, 1,
                    cv2.LINE_AA)


def save_png(path: str | Path, rgb: np.ndarray) -> None:
    """Write an RGB image to ``path`` (PNG); raises ValueError if it cannot be written."""
    arr = np.asarray(rgb)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {arr.shape} {arr.dtype}")
    if not cv2.imwrite(str(path), cv2.cvtColor(arr, cv2.COLOR_RGB2BGR)):
        raise ValueError(f"cannot write image to {path}")
