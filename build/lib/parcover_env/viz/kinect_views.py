"""Pictures of the Kinect model and pipeline: depth, IR, Fig. 7 stages, Fig. 9 hull, Fig. 10 trajectory.

Every function returns an RGB uint8 image; :func:`write_kinect_views` writes them as PNGs.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from parcover_env.geometry.camera import CameraModel
from parcover_env.localization.kinect.pipeline import PipelineParams, estimate_poses, find_blobs, pipeline_stages
from parcover_env.sensors.kinect import KinectFrame, KinectSensor

if TYPE_CHECKING:
    from parcover_env.config import Scenario

__all__ = ["depth_image", "ir_image", "stages_image", "hull_image", "trajectory_image", "write_kinect_views",
           "simulate_trajectory"]


def depth_image(depth: np.ndarray, z_range: tuple[float, float] | None = None) -> np.ndarray:
    """Depth (m, 0 = invalid) as a colour map; invalid pixels black."""
    d = np.asarray(depth, dtype=float)
    if d.ndim != 2:
        raise ValueError(f"depth must be 2-D, got shape {d.shape}")
    valid = d > 0
    lo, hi = z_range or ((float(d[valid].min()), float(d[valid].max())) if valid.any() else (0.0, 1.0))
    scaled = np.clip((d - lo) / max(hi - lo, 1e-6), 0, 1)
    img = cv2.applyColorMap((255 * (1 - scaled)).astype(np.uint8), cv2.COLORMAP_JET)
    img[~valid] = 0
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def ir_image(ir: np.ndarray) -> np.ndarray:
    """IR frame as RGB grey."""
    ir = np.asarray(ir)
    if ir.ndim != 2 or ir.dtype != np.uint8:
        raise ValueError(f"IR frame must be a 2-D uint8 array, got {ir.dtype} {ir.shape}")
    return np.repeat(ir[..., None], 3, axis=2)


def _label(img: np.ndarray, text: str) -> np.ndarray:
    out = img.copy()
    scale = max(0.4, img.shape[1] / 800)
    cv2.putText(out, text, (6, int(22 * scale + 4)), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 0), 1,
                cv2.LINE_AA)
    return out


def stages_image(ir: np.ndarray, params: PipelineParams | None = None) -> np.ndarray:
    """Fig. 7 (a)-(d) side by side: raw IR, median, threshold, morphology."""
    st = pipeline_stages(ir, params)
    names = ("raw", "median", "threshold", "morphology")
    tiles = [_label(ir_image(st[k]), f"({c}) {k}") for c, k in zip("abcd", names, strict=True)]
    sep = np.full((tiles[0].shape[0], 4, 3), 128, np.uint8)
    return np.concatenate([tiles[0], sep, tiles[1], sep, tiles[2], sep, tiles[3]], axis=1)


def hull_image(frame: KinectFrame, camera: CameraModel, params: PipelineParams | None = None) -> np.ndarray:
    """Fig. 9: the depth frame (a) and the marker hulls with the estimated poses drawn on it (b)."""
    p = params or PipelineParams()
    a = _label(depth_image(frame.depth), "(a) depth")
    b = depth_image(frame.depth)
    cents, labels, ids = find_blobs(frame.ir, p)
    for lab in ids:
        pix = cv2.findNonZero((labels == lab).astype(np.uint8))
        cv2.polylines(b, [cv2.convexHull(pix)], True, (255, 255, 255), 1)
    for e in estimate_poses(frame, camera, p):
        ahead = [e.x + 0.15 * np.cos(e.theta), e.y + 0.15 * np.sin(e.theta), p.marker_height]
        tip = np.array([[e.x, e.y, p.marker_height], ahead])
        uv, _ = camera.project(tip)
        q = np.rint(uv).astype(int)
        cv2.circle(b, tuple(q[0]), 3, (255, 0, 255), -1)
        cv2.arrowedLine(b, tuple(q[0]), tuple(q[1]), (255, 0, 255), 2)
    mask_all = np.isin(labels, ids).astype(np.uint8)
    for g_pix in _group_hulls(mask_all):
        cv2.polylines(b, [g_pix], True, (255, 0, 255), 1)
    b = _label(b, "(b) hull + pose")
    sep = np.full((a.shape[0], 4, 3), 128, np.uint8)
    return np.concatenate([a, sep, b], axis=1)


def _group_hulls(mask: np.ndarray) -> list[np.ndarray]:
    """Hulls of marker clusters for display (blobs merged by a dilation)."""
    k = max(3, mask.shape[1] // 20) | 1
    merged = cv2.dilate(mask, np.ones((k, k), np.uint8))
    n, lab = cv2.connectedComponents(merged)
    hulls = []
    for i in range(1, n):
        pix = cv2.findNonZero(((lab == i) & (mask > 0)).astype(np.uint8))
        if pix is not None:
            hulls.append(cv2.convexHull(pix))
    return hulls


def trajectory_image(true_xy: np.ndarray, est_xy: np.ndarray, title: str = "", size=(640, 480)) -> np.ndarray:
    """Fig. 10: estimated (red dashed) vs true (blue) trajectory, matplotlib Agg (imported lazily)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    true_xy, est_xy = np.asarray(true_xy, float).reshape(-1, 2), np.asarray(est_xy, float).reshape(-1, 2)
    fig = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    ax.plot(true_xy[:, 0], true_xy[:, 1], "b-", lw=1.5, label="ground truth")
    ax.plot(est_xy[:, 0], est_xy[:, 1], "r--", lw=1.2, label="Kinect estimate")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def simulate_trajectory(sensor: KinectSensor, start, v: float, omega: float, duration: float,
                        rng: np.random.Generator, params: PipelineParams | None = None):
    """Drive one robot (unicycle) from ``start (x, y, theta)`` at ``(v, omega)``, one frame per Kinect
    period; returns true poses ``(T, 3)``, estimates ``(T, 3)`` (NaN when missed)."""
    dt = 1.0 / sensor.cfg.rate_hz
    n = max(1, int(round(duration / dt)))
    true = np.empty((n, 3))
    est = np.full((n, 3), np.nan)
    pose = np.asarray(start, dtype=float).copy()
    for k in range(n):
        true[k] = pose
        ests = estimate_poses(sensor.measure(pose[None], [True], rng, stamp=k * dt), sensor.camera, params)
        if ests:
            best = min(ests, key=lambda e: np.hypot(e.x - pose[0], e.y - pose[1]))
            est[k] = best.pose
        pose = pose + dt * np.array([v * np.cos(pose[2]), v * np.sin(pose[2]), omega])
    return true, est


def _kinect_and_poses(scenario: Scenario) -> tuple[KinectSensor, np.ndarray]:
    from parcover_env.config import KinectConfig
    from parcover_env.world.map_model import map_model
    cfg = scenario.kinects[0] if scenario.kinects else \
        KinectConfig("overhead", (scenario.start.x, scenario.start.y))
    mm = map_model(scenario.map)
    sensor = KinectSensor(cfg, scenario.robot.radius, scenario.robot.height, mm)
    fp = sensor.camera.footprint().buffer(-2.5 * scenario.robot.radius)
    start = np.array([scenario.start.x, scenario.start.y])
    centre = np.array(fp.centroid.coords[0]) if not fp.is_empty else start
    cands = [start, centre] + [centre + 0.6 * np.array([np.cos(a), np.sin(a)]) for a in np.linspace(0, 6, 6)]
    chosen: list[np.ndarray] = []
    from shapely.geometry import Point

    for c in cands:
        if fp.contains(Point(c)) and mm.contains([c], margin=scenario.robot.radius)[0] and \
                all(np.hypot(*(c - q)) > 3 * scenario.robot.radius for q in chosen):
            chosen.append(c)
        if len(chosen) == 3:
            break
    if not chosen:
        chosen = [centre]
    poses = np.array([[c[0], c[1], 0.7 * i + scenario.start.theta] for i, c in enumerate(chosen)])
    return sensor, poses


def write_kinect_views(scenario: Scenario, out_dir, rng: np.random.Generator,
                       duration: float = 20.0) -> list[Path]:
    """Write depth, IR, Fig. 7 stages, Fig. 9 hull and Fig. 10 trajectory PNGs of the scenario's first
    Kinect (a default one over the start if it has none); returns the written paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sensor, poses = _kinect_and_poses(scenario)
    params = PipelineParams(marker_height=scenario.robot.height, robot_radius=scenario.robot.radius)
    frame = sensor.measure(poses, np.ones(len(poses), bool), rng)
    images = {
        "kinect_depth.png": depth_image(frame.depth),
        "kinect_ir.png": ir_image(frame.ir),
        "kinect_pipeline.png": stages_image(frame.ir, params),
        "kinect_hull.png": hull_image(frame, sensor.camera, params),
    }
    true, est = simulate_trajectory(sensor, poses[0], 0.08, 0.08, duration, rng, params)
    images["kinect_trajectory.png"] = trajectory_image(true[:, :2], est[:, :2], _rmse_title(true, est))
    paths = []
    for name, img in images.items():
        path = out / name
        cv2.imwrite(str(path), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
        paths.append(path)
    return paths


def _rmse_title(true: np.ndarray, est: np.ndarray, prefix: Sequence[str] = ()) -> str:
    ok = ~np.isnan(est[:, 0])
    if not ok.any():
        return "no detections"
    err = np.hypot(*(est[ok, :2] - true[ok, :2]).T)
    rmse_mm = 1000 * np.sqrt(np.mean(err ** 2))
    return " ".join([*prefix, f"pos RMSE {rmse_mm:.1f} mm, detected {ok.mean():.0%}"])
