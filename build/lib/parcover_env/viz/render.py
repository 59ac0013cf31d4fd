"""Top-down frames drawn with OpenCV (RGB uint8), and a GIF writer.

Rendering reads world state only; it never feeds back into observations.
"""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from parcover_env.scenarios import Mission
    from parcover_env.world.map_model import MapModel

__all__ = ["MapCanvas", "render_frame", "save_gif"]

WALL = (70, 70, 80)
FLOOR = (250, 250, 248)
KINECT = (120, 170, 255)
LEADER = (230, 120, 20)
FOLLOWER = (40, 110, 200)
KPOI_OPEN = (210, 40, 40)
KPOI_DONE = (40, 170, 70)
ROUTE = (200, 200, 210)


class MapCanvas:
    """World (m) -> pixel transform and a cached static background of a map."""

    def __init__(self, map_model: MapModel, target_px: int = 720, margin_px: int = 12):
        x0, y0, x1, y1 = map_model.bounds
        self.scale = (target_px - 2 * margin_px) / max(x1 - x0, y1 - y0)
        self.origin = np.array([x0, y0])
        self.margin = margin_px
        self.width = int(round((x1 - x0) * self.scale)) + 2 * margin_px
        self.height = int(round((y1 - y0) * self.scale)) + 2 * margin_px
        self.background = np.full((self.height, self.width, 3), WALL, dtype=np.uint8)
        for poly in getattr(map_model.free, "geoms", [map_model.free]):
            cv2.fillPoly(self.background, [self.px(np.array(poly.exterior.coords))], FLOOR, cv2.LINE_AA)
            for hole in poly.interiors:
                cv2.fillPoly(self.background, [self.px(np.array(hole.coords))], WALL, cv2.LINE_AA)

    def px(self, xy) -> np.ndarray:
        """World points ``(..., 2)`` -> integer pixel coordinates (y axis flipped)."""
        p = (np.asarray(xy, dtype=float) - self.origin) * self.scale
        out = np.empty(p.shape, dtype=np.int32)
        out[..., 0] = np.round(p[..., 0] + self.margin)
        out[..., 1] = np.round(self.height - self.margin - p[..., 1])
        return out

    def r(self, metres: float) -> int:
        return max(1, int(round(metres * self.scale)))


def _overlay_polygon(img: np.ndarray, pts: np.ndarray, color, alpha: float) -> None:
    layer = img.copy()
    cv2.fillPoly(layer, [pts], color, cv2.LINE_AA)
    cv2.addWeighted(layer, alpha, img, 1 - alpha, 0, dst=img)
    cv2.polylines(img, [pts], True, color, 1, cv2.LINE_AA)


@lru_cache(maxsize=16)
def _static_layer(mission: Mission) -> tuple[MapCanvas, np.ndarray]:
    """Canvas and background of a mission: map, Kinect footprints, routes, TPs, start (drawn once)."""
    from parcover_env.geometry.camera import CameraModel

    canvas = MapCanvas(mission.map)
    img = canvas.background.copy()
    s = mission.scenario
    for kin in s.kinects:
        fp = CameraModel.from_config(kin).footprint()
        if not fp.is_empty:
            pts = canvas.px(np.array(fp.exterior.coords))
            _overlay_polygon(img, pts, KINECT, 0.18)
            cv2.putText(img, kin.name, tuple(int(v) for v in pts.min(axis=0) + 4 + [0, 12]),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.45, KINECT, 1, cv2.LINE_AA)
    for route in mission.routes:
        cv2.polylines(img, [canvas.px(route)], False, ROUTE, 1, cv2.LINE_AA)
    for tp in mission.plan.turning_points:
        p = canvas.px(tp.position)
        tri = np.array([p + [0, -8], p + [-7, 5], p + [7, 5]], dtype=np.int32)
        cv2.fillPoly(img, [tri], (240, 200, 0), cv2.LINE_AA)
    start = canvas.px([s.start.x, s.start.y])
    cv2.circle(img, tuple(start), 9, (90, 90, 90), 1, cv2.LINE_AA)
    cv2.putText(img, "S", tuple(start + [-4, 4]), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (90, 90, 90), 1, cv2.LINE_AA)
    img.setflags(write=False)
    return canvas, img


def render_frame(env) -> np.ndarray:
    """The env's current top-down frame (RGB uint8); reads the env's public state only."""
    canvas, background = _static_layer(env.mission)
    img = background.copy()
    s = env.scenario
    half = max(4, canvas.r(s.kpoi_radius) // 2)
    for k, (p, done) in enumerate(zip(canvas.px(np.array(s.kpois)), env.progress.visited)):
        color = KPOI_DONE if done else KPOI_OPEN
        cv2.rectangle(img, tuple(p - half), tuple(p + half), color, 2, cv2.LINE_AA)
        cv2.putText(img, str(k + 1), tuple(p + [half + 2, -half]), cv2.FONT_HERSHEY_SIMPLEX, 0.35, color, 1,
                    cv2.LINE_AA)
    true = env.world.poses()
    rad = canvas.r(s.robot.radius)
    for i, p in enumerate(true):
        color = LEADER if env.team.leader[i] else FOLLOWER
        if len(env.trails[i]) > 1:
            cv2.polylines(img, [canvas.px(np.array(env.trails[i]))], False, color, 1, cv2.LINE_AA)
        c = canvas.px(p[:2])
        cv2.circle(img, tuple(c), rad, color, -1, cv2.LINE_AA)
        tip = canvas.px(p[:2] + s.robot.radius * np.array([np.cos(p[2]), np.sin(p[2])]))
        cv2.line(img, tuple(c), tuple(tip), (255, 255, 255), max(1, rad // 4), cv2.LINE_AA)
    label = f"{s.name}  t={env.world.time:5.1f}s  KPOIs {int(env.progress.visited.sum())}/{len(s.kpois)}"
    cv2.putText(img, label, (canvas.margin + 2, canvas.margin + 12), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                (255, 255, 255), 1, cv2.LINE_AA)
    return img


def save_gif(path, frames: list[np.ndarray], fps: int = 10) -> None:
    """Write RGB frames to an animated GIF."""
    import imageio.v2 as imageio

    imageio.mimsave(path, frames, duration=1.0 / fps, loop=0)
