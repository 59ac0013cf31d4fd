"""Top-down frames drawn with OpenCV (RGB uint8): a header band, the map, a legend; a streaming
GIF writer and the ``human`` render window.

Rendering reads world state only; it never feeds back into observations.
"""

from __future__ import annotations

import contextlib
from functools import lru_cache
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from parcover_env.scenarios import Mission
    from parcover_env.world.map_model import MapModel

__all__ = ["MapCanvas", "render_frame", "save_gif", "GifRecorder", "kpoi_label", "show_frame", "close_window",
           "HEADER_PX", "LEGEND_PX"]

WALL = (70, 70, 80)
FLOOR = (250, 250, 248)
KINECT = (120, 170, 255)
LEADER = (230, 120, 20)
FOLLOWER = (40, 110, 200)
KPOI_OPEN = (210, 40, 40)
KPOI_DONE = (40, 170, 70)
ROUTE = (200, 200, 210)
TP = (240, 200, 0)
BAND = (35, 35, 45)
BAND_TEXT = (245, 245, 245)
HEADER_PX = 28
"""Height of the header band above the map (px)."""
LEGEND_PX = 26
"""Height of the legend band below the map (px)."""
_FONT = cv2.FONT_HERSHEY_SIMPLEX


def kpoi_label(index: int) -> str:
    """Label of KPOI ``index`` (0-based in the scenario) in every drawing: ``K1``, ``K2``, ..."""
    return f"K{index + 1}"


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
        cv2.fillPoly(img, [tri], TP, cv2.LINE_AA)
    start = canvas.px([s.start.x, s.start.y])
    cv2.circle(img, tuple(start), 9, (90, 90, 90), 1, cv2.LINE_AA)
    cv2.putText(img, "S", tuple(start + [-4, 4]), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (90, 90, 90), 1, cv2.LINE_AA)
    img = np.concatenate([np.full((HEADER_PX, canvas.width, 3), BAND, np.uint8), img, _legend(canvas.width)])
    img.setflags(write=False)
    return canvas, img


def _legend(width: int) -> np.ndarray:
    """The legend band: swatches for leader, follower, KPOI to visit / visited, TP, route, Kinect."""
    band = np.full((LEGEND_PX, width, 3), BAND, np.uint8)
    y, x = LEGEND_PX // 2, 8
    items = [("leader", LEADER, "disc"), ("follower", FOLLOWER, "disc"), ("KPOI to visit", KPOI_OPEN, "box"),
             ("visited", KPOI_DONE, "box"), ("TP", TP, "tri"), ("route", ROUTE, "line"), ("Kinect", KINECT, "box")]
    for text, color, mark in items:
        if mark == "disc":
            cv2.circle(band, (x + 5, y), 5, color, -1, cv2.LINE_AA)
        elif mark == "box":
            cv2.rectangle(band, (x, y - 5), (x + 10, y + 5), color, 2)
        elif mark == "tri":
            cv2.fillPoly(band, [np.array([[x + 5, y - 6], [x, y + 5], [x + 10, y + 5]], np.int32)], color, cv2.LINE_AA)
        else:
            cv2.line(band, (x, y), (x + 10, y), color, 2, cv2.LINE_AA)
        cv2.putText(band, text, (x + 14, y + 5), _FONT, 0.42, BAND_TEXT, 1, cv2.LINE_AA)
        x += 14 + cv2.getTextSize(text, _FONT, 0.42, 1)[0][0] + 14
        if x > width - 40:
            break
    return band


def render_frame(env) -> np.ndarray:
    """The env's current top-down frame (RGB uint8); reads the env's public state only."""
    canvas, background = _static_layer(env.mission)
    frame = background.copy()
    img = frame[HEADER_PX:HEADER_PX + canvas.height]  # the map area (a view: drawing on it draws on the frame)
    s = env.scenario
    half = max(4, canvas.r(s.kpoi_radius) // 2)
    for k, (p, done) in enumerate(zip(canvas.px(np.array(s.kpois)), env.progress.visited)):
        color = KPOI_DONE if done else KPOI_OPEN
        cv2.rectangle(img, tuple(p - half), tuple(p + half), color, 2, cv2.LINE_AA)
        cv2.putText(img, kpoi_label(k), tuple(p + [half + 2, -half]), _FONT, 0.4, color, 1, cv2.LINE_AA)
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
    label = (f"{s.name}   t = {env.world.time:6.1f} s   step {env.steps}   "
             f"KPOIs {int(env.progress.visited.sum())}/{len(s.kpois)}   robots {env.n_robots}")
    cv2.putText(frame, label, (8, HEADER_PX - 9), _FONT, 0.55, BAND_TEXT, 1, cv2.LINE_AA)
    return frame


GIF_QUANTIZER = 2
"""Pillow quantizer of the streaming GIF writer: 2 = fast octree. (Median cut, 0, can give palettes of
fewer than 256 colours, which the streaming writer then encodes into an unreadable file.)"""


class GifRecorder:
    """Animated GIF written frame by frame (imageio's streaming Pillow GIF writer): memory stays at
    a few frames whatever the episode length. Keeps every ``every``-th frame and always the last
    one; ``append`` has the ``list.append`` signature, so it can stand in for a frame list."""

    def __init__(self, path, every: int = 1, fps: float = 10.0):
        import imageio.v2 as imageio

        if every < 1:
            raise ValueError(f"every must be >= 1, got {every}")
        self.path, self.every = path, int(every)
        self._writer = imageio.get_writer(path, format="GIF-PIL", mode="I", duration=1.0 / fps, loop=0,
                                          quantizer=GIF_QUANTIZER)
        self._seen = 0
        self._pending: np.ndarray | None = None  # last frame not yet written (written at close)
        self.written = 0

    def append(self, frame: np.ndarray) -> None:
        if self._seen % self.every == 0:
            self._write(frame)
            self._pending = None
        else:
            self._pending = frame
        self._seen += 1

    def _write(self, frame: np.ndarray) -> None:
        self._writer.append_data(np.asarray(frame))
        self.written += 1

    def close(self) -> None:
        """Write the final frame (if it was skipped) and finish the file."""
        if self._writer is None:
            return
        if self._pending is not None:
            self._write(self._pending)
            self._pending = None
        self._writer.close()
        self._writer = None

    def __enter__(self) -> GifRecorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def save_gif(path, frames, fps: float = 10.0, every: int = 1) -> int:
    """Write RGB frames (any iterable) to an animated GIF, streaming; returns the frames written."""
    with GifRecorder(path, every=every, fps=fps) as rec:
        for f in frames:
            rec.append(f)
    return rec.written


def _has_display() -> bool:
    import os
    import sys

    return sys.platform in ("win32", "darwin") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


_WARNED: set[str] = set()
"""The reasons ``human`` rendering showed nothing that this process has already warned about."""


def show_frame(frame: np.ndarray, window: str, wait_ms: int) -> str | None:
    """Show an RGB frame in an OpenCV window (the ``human`` render mode); returns the window name.

    Without a display (no DISPLAY/WAYLAND_DISPLAY) or with an OpenCV built without GUI support
    (``opencv-python-headless``) it shows nothing and returns None, and warns once per process and
    reason (a ``UserWarning``): ``render_mode="human"`` runs headless, as the Gymnasium and
    PettingZoo checkers build it."""
    if not _has_display():
        return _no_window("no display (DISPLAY/WAYLAND_DISPLAY unset)")
    try:
        cv2.imshow(window, cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
        cv2.waitKey(max(1, int(wait_ms)))
    except cv2.error:
        return _no_window("OpenCV has no GUI support (pip install opencv-python, not opencv-python-headless)")
    return window


def _no_window(reason: str) -> None:
    import warnings

    if reason in _WARNED:
        return None
    _WARNED.add(reason)
    warnings.warn(f"render_mode='human' shows nothing: {reason}; use render_mode='rgb_array' for frames",
                  UserWarning, stacklevel=4)
    return None


def close_window(window: str) -> None:
    """Close a window opened by :func:`show_frame`."""
    with contextlib.suppress(cv2.error):
        cv2.destroyWindow(window)
