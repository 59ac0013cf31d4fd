"""Compiled (numba) body of the Kinect *estimate* model (:func:`~parcover_env.localization.kinect.
pipeline.estimate_fast`); import only through that module.

One call for the Kinects due at a step: view-box filter, marker projection, visibility and wall-top occlusion tests,
detection and error draws from the episode's generator (numba's generator methods advance the same
state and return the same numbers as numpy's), and the pose the pipeline would reconstruct through
the nominal camera. Projections are written out per coordinate (no BLAS), so they give the same
numbers on every CPU. ``tests/localization/test_kinect_fast.py`` keeps a numpy reference.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _project(R, C, fu, fv, cu, cv, x, y, z):
    """World point -> ``(u, v, depth)`` through a pinhole camera (``R`` world->camera, centre ``C``)."""
    px = x - C[0]
    py = y - C[1]
    pz = z - C[2]
    xc = px * R[0, 0] + py * R[0, 1] + pz * R[0, 2]
    yc = px * R[1, 0] + py * R[1, 1] + pz * R[1, 2]
    zc = px * R[2, 0] + py * R[2, 1] + pz * R[2, 2]
    return xc / zc * fu + cu, yc / zc * fv + cv, zc


@njit(cache=True, inline="always")
def _onto_plane(R, C, K, u, v, height):
    """Pixel ``(u, v)`` cast through a camera onto the plane ``z = height``: world ``(x, y)``; NaN
    if the ray does not reach the plane in front of the camera."""
    xc = (u - K[2]) / K[0]
    yc = (v - K[3]) / K[1]
    rx = xc * R[0, 0] + yc * R[1, 0] + R[2, 0]
    ry = xc * R[0, 1] + yc * R[1, 1] + R[2, 1]
    rz = xc * R[0, 2] + yc * R[1, 2] + R[2, 2]
    t = (height - C[2]) / rz
    if not (math.isfinite(t) and t > 0.0):
        return np.nan, np.nan
    return C[0] + rx * t, C[1] + ry * t


@njit(cache=True, nogil=True, error_model="numpy")
def estimate(due, poses, carriers, box, use_box, pattern, true_R, true_C, true_K, nom_R, nom_C, nom_K, remounted,
             depths, size, scal, noise, rng, out_sensor, out_index, out_pose):
    """Detections of the Kinects ``due`` (in that order): fills ``out_sensor[:n]`` (positions in
    ``due``), ``out_index[:n]``
    (robot indices, ascending per Kinect) and ``out_pose[:n]`` (x, y, theta); returns ``n``.

    Per Kinect ``q`` (the arrays of :class:`~parcover_env.localization.kinect.pipeline.FastModel`):
    ``box[q]`` (x0, y0, x1, y1), the floor box outside which no carrier is seen (if ``use_box[q]``);
    the marker ``pattern[q]``; the mounted camera ``true_R/C/K[q]`` (K = fu, fv, cu, cv) and the
    nominal one the pipeline believes in (``remounted[q]``: they differ; else the true pose is the
    reconstructed one); the nominal static depth ``depths[q]``; ``size[q]`` = (width, height) px;
    ``scal[q]`` = marker radius, marker height, range min, range max, drop rate, pattern gap (m),
    resolution scale ``(640 / width) ** res_exponent``, pattern span (m). ``noise`` = margin px,
    closing limit px, r_px_min, r_px_full, pos_px, heading_px (:class:`FastNoise`). Draws per
    Kinect: one uniform for the frame drop (if its rate > 0), then per visible resolvable carrier
    one uniform (detection), two normals (x, y) and one normal (heading)."""
    margin_px, close_px, r_px_min, r_px_full, pos_px, heading_px = noise[0], noise[1], noise[2], noise[3], \
        noise[4], noise[5]
    n = 0
    for p in range(due.shape[0]):
        q = due[p]
        radius, height, range_min, range_max, drop_rate, gap, res_scale, span = scal[q, 0], scal[q, 1], \
            scal[q, 2], scal[q, 3], scal[q, 4], scal[q, 5], scal[q, 6], scal[q, 7]
        if drop_rate > 0.0 and rng.random() < drop_rate:
            continue
        R, C = true_R[q], true_C[q]
        fu, fv, cu, cv = true_K[q, 0], true_K[q, 1], true_K[q, 2], true_K[q, 3]
        static_depth = depths[q]
        width, height_px = size[q, 0], size[q, 1]
        k = pattern.shape[1]
        for i in carriers:
            x = poses[i, 0]
            y = poses[i, 1]
            if use_box[q] and not (x >= box[q, 0] and x <= box[q, 2] and y >= box[q, 1] and y <= box[q, 3]):
                continue
            c = math.cos(poses[i, 2])
            s = math.sin(poses[i, 2])
            ok = True
            z_max = -np.inf
            z_sum = 0.0
            for j in range(k):
                px = pattern[q, j, 0]
                py = pattern[q, j, 1]
                u, v, z = _project(R, C, fu, fv, cu, cv, x + c * px - s * py, y + s * px + c * py, height)
                r_px = radius * fu / z + margin_px
                if not (z > 0.0 and u - r_px >= 0.0 and u + r_px <= width - 1 and v - r_px >= 0.0
                        and v + r_px <= height_px - 1 and z >= range_min and z <= range_max):
                    ok = False
                    break
                if static_depth[int(np.rint(v)), int(np.rint(u))] < z - 1e-6:
                    ok = False  # a wall top nearer than the marker hides it
                    break
                z_max = max(z_max, z)
                z_sum += z
            if not ok:
                continue
            p_det = min(max((radius * fu / z_max - r_px_min) / (r_px_full - r_px_min), 0.0), 1.0)
            if gap * (nom_K[q, 0] / z_max) < close_px or rng.random() >= p_det:
                continue  # markers merged by the closing, or too small to be found
            mpp = (z_sum / k) / fu * res_scale
            ex = rng.normal(0.0, pos_px * mpp)
            ey = rng.normal(0.0, pos_px * mpp)
            eth = rng.normal(0.0, heading_px * mpp / span)
            bx, by, th = x, y, poses[i, 2]
            if remounted[q]:  # the pose as the pipeline reconstructs it: centre and a point ahead,
                # imaged by the true camera, cast onto the marker plane with the nominal one
                u0, v0, _ = _project(R, C, fu, fv, cu, cv, x, y, height)
                u1, v1, _ = _project(R, C, fu, fv, cu, cv, x + 0.1 * c, y + 0.1 * s, height)
                bx, by = _onto_plane(nom_R[q], nom_C[q], nom_K[q], u0, v0, height)
                ax, ay = _onto_plane(nom_R[q], nom_C[q], nom_K[q], u1, v1, height)
                th = math.atan2(ay - by, ax - bx)
            th = th + eth
            out_sensor[n] = p
            out_index[n] = i
            out_pose[n, 0] = bx + ex
            out_pose[n, 1] = by + ey
            out_pose[n, 2] = math.pi - ((math.pi - th) % (2.0 * math.pi))
            n += 1
    return n
