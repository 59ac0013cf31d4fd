"""References of the Kinect's compiled loops as numpy formulas: :func:`render`
(:func:`~parcover_env.sensors.kinect_kernels.draw_robots` and
:func:`~parcover_env.sensors.kinect_kernels.marker_codes`) and :func:`estimates`
(:func:`~parcover_env.localization.kinect.estimate_kernel.estimate`, one Kinect, with
:func:`project` and :func:`onto_plane`)."""

from __future__ import annotations

import math

import numpy as np

from parcover_env.geometry import wrap_angle
from parcover_env.localization.kinect.estimate_model import FastNoise
from parcover_env.sensors.kinect import NATIVE_WIDTH, KinectSensor


def render(s: KinectSensor, poses: np.ndarray, marker_mask: np.ndarray):
    """Robots and marker codes drawn with numpy, one robot at a time, from the formulas of
    :meth:`KinectSensor.render_clean` (the code the compiled loops replaced)."""
    depth = s.static_depth.copy()
    owner = np.full(s.shape, -1, dtype=np.int32)
    top = np.zeros(s.shape, dtype=bool)
    C, r2 = s.true_camera.C, s.robot_radius ** 2
    boxes = s._robot_boxes(poses[:, :2])
    for i, (x, y, _) in enumerate(poses):
        if boxes[i, 0] < 0:
            continue
        u0, v0, u1, v1 = boxes[i]
        D = s.rays[v0:v1, u0:u1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t_top = (s.robot_height - C[2]) / D[..., 2]
            px, py = C[0] + D[..., 0] * t_top - x, C[1] + D[..., 1] * t_top - y
            on_top = (t_top > 0) & (px * px + py * py <= r2)
            ox, oy = C[0] - x, C[1] - y
            a = D[..., 0] ** 2 + D[..., 1] ** 2
            b = ox * D[..., 0] + oy * D[..., 1]
            disc = b * b - a * (ox * ox + oy * oy - r2)
            t_side = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
            z_side = C[2] + t_side * D[..., 2]
        on_side = (disc > 0) & (t_side > 0) & (z_side >= 0) & (z_side <= s.robot_height)
        t = np.minimum(np.where(on_top, t_top, np.inf), np.where(on_side, t_side, np.inf))
        sub = depth[v0:v1, u0:u1]
        closer = t < sub
        sub[closer] = t[closer]
        owner[v0:v1, u0:u1][closer] = i
        top[v0:v1, u0:u1][closer] = on_top[closer] & (t_top[closer] <= t[closer])
    code = np.zeros(s.shape, dtype=np.uint8)
    for i, (x, y, th) in enumerate(poses):
        if not marker_mask[i] or boxes[i, 0] < 0:
            continue
        u0, v0, u1, v1 = boxes[i]
        mine = (owner[v0:v1, u0:u1] == i) & top[v0:v1, u0:u1]
        t = depth[v0:v1, u0:u1][mine]
        D = s.rays[v0:v1, u0:u1][mine]
        p = C[:2] + D[:, :2] * t[:, None] - (x, y)
        c, sn = math.cos(th), math.sin(th)
        q = np.stack([c * p[:, 0] + sn * p[:, 1], -sn * p[:, 0] + c * p[:, 1]], axis=1)
        d2 = ((q[:, None, :] - s.pattern[None]) ** 2).sum(-1).min(axis=1)
        code[v0:v1, u0:u1][mine] = np.where(d2 <= s.marker_radius ** 2, 1,
                                            np.where(d2 <= (s.marker_radius * s.missing_factor) ** 2, 2, 0))
    return depth, owner, code


def project(cam, pts):
    pc = (pts - cam.C) @ cam.R.T
    with np.errstate(divide="ignore", invalid="ignore"):
        return (pc[:, :2] / pc[:, 2:3]) * np.diag(cam.K)[:2] + cam.K[:2, 2], pc[:, 2]


def onto_plane(cam, uv, height):
    xc = (uv[:, 0] - cam.K[0, 2]) / cam.K[0, 0]
    yc = (uv[:, 1] - cam.K[1, 2]) / cam.K[1, 1]
    rays = np.stack([xc, yc, np.ones_like(xc)], axis=1) @ cam.R
    t = (height - cam.C[2]) / rays[:, 2]
    return np.where(((t > 0) & np.isfinite(t))[:, None], cam.C[:2] + rays[:, :2] * t[:, None], np.nan)


def estimates(s, poses, mask, rng):
    """One Kinect's estimate model as numpy formulas (no view-box pre-filter: it rejects nothing more)."""
    nz = FastNoise()
    if s.cfg.drop_rate > 0 and rng.random() < s.cfg.drop_rate:
        return []
    cam, pat, h, (rows, cols) = s.true_camera, s.pattern, s.robot_height, s.shape
    out = []
    for i in np.flatnonzero(mask):
        x, y, th = poses[i]
        c, sn = math.cos(th), math.sin(th)
        world = np.column_stack([x + c * pat[:, 0] - sn * pat[:, 1], y + sn * pat[:, 0] + c * pat[:, 1],
                                 np.full(len(pat), h)])
        uv, z = project(cam, world)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = s.marker_radius * cam.focal / z + nz.margin_px
        inside = (z > 0) & (uv[:, 0] - r >= 0) & (uv[:, 0] + r <= cols - 1) & (uv[:, 1] - r >= 0) \
            & (uv[:, 1] + r <= rows - 1) & (z >= cam.range_min) & (z <= cam.range_max)
        if not inside.all():
            continue
        if np.any(s.nominal_static_depth[np.rint(uv[:, 1]).astype(int), np.rint(uv[:, 0]).astype(int)] < z - 1e-6):
            continue
        p_det = min(max((s.marker_radius * cam.focal / z.max() - nz.r_px_min) / (nz.r_px_full - nz.r_px_min), 0), 1)
        gaps = np.linalg.norm(pat[:, None] - pat[None], axis=-1) + np.eye(len(pat)) * 1e9
        gap_px = (gaps.min() - 2 * s.marker_radius) * s.camera.focal / z.max()
        if gap_px < 3 or rng.random() >= p_det:
            continue
        mpp = z.mean() / cam.focal * (NATIVE_WIDTH / cols) ** nz.res_exponent
        ex, ey = rng.normal(0.0, nz.pos_px * mpp, size=2)
        eth = rng.normal(0.0, nz.heading_px * mpp / (np.ptp(pat[:, 0]) or 0.1))
        if cam is not s.camera:
            uv2, _ = project(cam, np.array([[x, y, h], [x + 0.1 * c, y + 0.1 * sn, h]]))
            back = onto_plane(s.camera, uv2, h)
            x, y, th = back[0, 0], back[0, 1], math.atan2(back[1, 1] - back[0, 1], back[1, 0] - back[0, 0])
        out.append((int(i), x + ex, y + ey, float(wrap_angle(th + eth))))
    return out
