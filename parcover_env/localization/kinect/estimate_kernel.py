"""Compiled (numba) body of the Kinect *estimate* model, the internals of
:mod:`parcover_env.localization.kinect.estimate_model` (public so that tests and other rooms may use
it). Its constants are records (structured arrays, :mod:`parcover_env.geometry.records`): a
:data:`KINECT` row per Kinect and the :data:`FAST_NOISE` record.

One call for the Kinects due at a step: view-box filter, marker projection, visibility and wall-top occlusion tests,
detection and error draws from the episode's generator (numba's generator methods advance the same
state and return the same numbers as numpy's), and the pose the pipeline would reconstruct through
the nominal camera. Projections are written out per coordinate (no BLAS), so they give the same
numbers on every CPU. ``tests/references/kinect.py`` keeps a numpy reference.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from parcover_env.geometry.angle_kernels import wrap

__all__ = ["KINECT", "FAST_NOISE", "estimate", "candidates"]

KINECT = np.dtype([
    ("box", "f8", (4,)),  # floor box (x0, y0, x1, y1) outside which no carrier is seen, if use_box (m)
    ("use_box", "?"),
    ("R", "f8", (3, 3)),  # the mounted camera: rotation world -> camera,
    ("C", "f8", (3,)),  # centre (m),
    ("K", "f8", (4,)),  # intrinsics fu, fv, cu, cv (px)
    ("nominal_R", "f8", (3, 3)),  # the camera the pipeline believes in
    ("nominal_C", "f8", (3,)),
    ("nominal_K", "f8", (4,)),
    ("remounted", "?"),  # the two cameras differ (else the true pose is the reconstructed one)
    ("width", "i8"),  # image size (px)
    ("height", "i8"),
    ("marker_radius", "f8"),  # (m)
    ("marker_height", "f8"),  # height of the marker plane, the robots' top (m)
    ("range_min", "f8"),  # valid depth (m)
    ("range_max", "f8"),
    ("drop_rate", "f8"),  # probability that a frame is dropped
    ("pattern_gap", "f8"),  # smallest edge-to-edge distance between two markers (m)
    ("res_scale", "f8"),  # (640 / width) ** res_exponent
    ("pattern_span", "f8"),  # extent of the pattern along the robot's x (m)
])
"""One Kinect of the estimate model (:class:`~parcover_env.localization.kinect.estimate_model.FastModel`)."""

FAST_NOISE = np.dtype([
    ("margin_px", "f8"),  # markers this close to the image border are not seen (px)
    ("close_px", "f8"),  # markers closer than this merge in the closing (px)
    ("r_px_min", "f8"),  # detection probability ramps from 0 at this marker radius (px) ...
    ("r_px_full", "f8"),  # ... to 1 at this one (px)
    ("pos_px", "f8"),  # position error sigma per axis (px at the robot's depth)
    ("heading_px", "f8"),  # heading error sigma times the pattern span (px)
])
"""The error model of the estimate model
(:class:`~parcover_env.localization.kinect.estimate_model.FastNoise`)."""


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


@njit(cache=True, inline="always")
def _seen(kin, pattern_q, static_depth, x, y, c, s, margin_px):
    """A carrier at ``(x, y)`` heading ``(cos, sin) = (c, s)`` as Kinect ``kin`` (a :data:`KINECT`
    row, marker pattern ``pattern_q (K, 2)``, static depth ``static_depth``) images it:
    ``(seen, z_max, z_sum)``, seen when every marker disc projects inside the image (``margin_px``
    from its border) within the depth range and no wall top is nearer; the markers' largest and
    summed depths (m)."""
    R, C = kin.R, kin.C
    fu, fv, cu, cv = kin.K[0], kin.K[1], kin.K[2], kin.K[3]
    radius, height = kin.marker_radius, kin.marker_height
    z_max = -np.inf
    z_sum = 0.0
    for j in range(pattern_q.shape[0]):
        px = pattern_q[j, 0]
        py = pattern_q[j, 1]
        u, v, z = _project(R, C, fu, fv, cu, cv, x + c * px - s * py, y + s * px + c * py, height)
        r_px = radius * fu / z + margin_px
        if not (z > 0.0 and u - r_px >= 0.0 and u + r_px <= kin.width - 1 and v - r_px >= 0.0
                and v + r_px <= kin.height - 1 and z >= kin.range_min and z <= kin.range_max):
            return False, z_max, z_sum
        if static_depth[int(np.rint(v)), int(np.rint(u))] < z - 1e-6:
            return False, z_max, z_sum  # a wall top nearer than the marker hides it
        z_max = max(z_max, z)
        z_sum += z
    return True, z_max, z_sum


@njit(cache=True, inline="always")
def _reconstructed(kin, x, y, c, s, theta):
    """The pose the pipeline reconstructs for a carrier at ``(x, y, theta)`` (``c, s`` its heading's
    cosine and sine): the true pose through an unmoved camera; through a remounted one, its centre
    and a point 0.1 m ahead imaged by the true camera and cast onto the marker plane with the nominal
    one."""
    if not kin.remounted:
        return x, y, theta
    R, C, height = kin.R, kin.C, kin.marker_height
    fu, fv, cu, cv = kin.K[0], kin.K[1], kin.K[2], kin.K[3]
    u0, v0, _ = _project(R, C, fu, fv, cu, cv, x, y, height)
    u1, v1, _ = _project(R, C, fu, fv, cu, cv, x + 0.1 * c, y + 0.1 * s, height)
    bx, by = _onto_plane(kin.nominal_R, kin.nominal_C, kin.nominal_K, u0, v0, height)
    ax, ay = _onto_plane(kin.nominal_R, kin.nominal_C, kin.nominal_K, u1, v1, height)
    return bx, by, math.atan2(ay - by, ax - bx)


@njit(cache=True, nogil=True, error_model="numpy")
def estimate(due, poses, carriers, kinects, pattern, depths, noise, rng, out_sensor, out_index, out_pose):
    """Detections of the Kinects ``due`` (in that order) of the robots ``carriers`` among ``poses
    (N, 3)``: fills ``out_sensor[:n]`` (positions in ``due``), ``out_index[:n]`` (robot indices,
    ascending per Kinect) and ``out_pose[:n]`` (x, y, theta); returns ``n``.

    Per Kinect ``q``: its :data:`KINECT` row ``kinects[q]``, its marker ``pattern[q] (K, 2)`` (robot
    frame, m) and its nominal static depth ``depths[q]``; ``noise`` is the :data:`FAST_NOISE` record.
    Draws from the numpy ``rng`` per Kinect: one uniform for the frame drop (if its rate > 0), then
    per visible resolvable carrier one uniform (detection), two normals (x, y) and one normal
    (heading)."""
    nz = noise[0]
    n = 0
    k = pattern.shape[1]
    for p in range(due.shape[0]):
        q = due[p]
        kin = kinects[q]
        if kin.drop_rate > 0.0 and rng.random() < kin.drop_rate:
            continue
        fu = kin.K[0]
        for i in carriers:
            x = poses[i, 0]
            y = poses[i, 1]
            box = kin.box
            if kin.use_box and not (x >= box[0] and x <= box[2] and y >= box[1] and y <= box[3]):
                continue
            c = math.cos(poses[i, 2])
            s = math.sin(poses[i, 2])
            seen, z_max, z_sum = _seen(kin, pattern[q], depths[q], x, y, c, s, nz.margin_px)
            if not seen:
                continue
            p_det = min(max((kin.marker_radius * fu / z_max - nz.r_px_min) / (nz.r_px_full - nz.r_px_min), 0.0), 1.0)
            if kin.pattern_gap * (kin.nominal_K[0] / z_max) < nz.close_px or rng.random() >= p_det:
                continue  # markers merged by the closing, or too small to be found
            mpp = (z_sum / k) / fu * kin.res_scale
            ex = rng.normal(0.0, nz.pos_px * mpp)
            ey = rng.normal(0.0, nz.pos_px * mpp)
            eth = rng.normal(0.0, nz.heading_px * mpp / kin.pattern_span)
            bx, by, th = _reconstructed(kin, x, y, c, s, poses[i, 2])
            th = th + eth
            out_sensor[n] = p
            out_index[n] = i
            out_pose[n, 0] = bx + ex
            out_pose[n, 1] = by + ey
            out_pose[n, 2] = wrap(th)
            n += 1
    return n


@njit(cache=True, nogil=True, error_model="numpy")
def candidates(rows, poses, carriers, kinects, pattern, depths, noise, row_drop, out_row, out_index, out_geom):
    """The random-free part of :func:`estimate` for many worlds at once. For every due Kinect (row
    ``r`` of ``rows (3, R)``: :data:`KINECT` row ``kinects[rows[0, r]]``, marker pattern
    ``pattern[rows[0, r]]``, static depth ``depths[rows[2, r]]``) of world ``rows[1, r]``, writes its
    frame drop rate to ``row_drop[r]``; for every carrier (``carriers (K, N)`` bool, ascending) among
    that world's ``poses (K, N, 3)`` that the Kinect images whole and unhidden, fills ``out_row[:n]``
    (``r``), ``out_index[:n]`` (robot index) and ``out_geom[:n]``: detection probability, merged (1.0:
    the markers merge in the closing, no draw), position and heading error sigmas, and the pose
    ``(x, y, theta)`` the pipeline reconstructs before noise; returns ``n``. The same float operations
    as :func:`estimate`; the caller draws (:mod:`~parcover_env.localization.kinect.batch_update`)."""
    nz = noise[0]
    n = 0
    k = pattern.shape[1]
    for r in range(rows.shape[1]):
        q = rows[0, r]
        w = rows[1, r]
        kin = kinects[q]
        row_drop[r] = kin.drop_rate
        fu = kin.K[0]
        for i in range(poses.shape[1]):
            if not carriers[w, i]:
                continue
            x = poses[w, i, 0]
            y = poses[w, i, 1]
            box = kin.box
            if kin.use_box and not (x >= box[0] and x <= box[2] and y >= box[1] and y <= box[3]):
                continue
            c = math.cos(poses[w, i, 2])
            s = math.sin(poses[w, i, 2])
            seen, z_max, z_sum = _seen(kin, pattern[q], depths[rows[2, r]], x, y, c, s, nz.margin_px)
            if not seen:
                continue
            p_det = min(max((kin.marker_radius * fu / z_max - nz.r_px_min) / (nz.r_px_full - nz.r_px_min), 0.0), 1.0)
            mpp = (z_sum / k) / fu * kin.res_scale
            bx, by, th = _reconstructed(kin, x, y, c, s, poses[w, i, 2])
            out_row[n] = r
            out_index[n] = i
            out_geom[n, 0] = p_det
            out_geom[n, 1] = 1.0 if kin.pattern_gap * (kin.nominal_K[0] / z_max) < nz.close_px else 0.0
            out_geom[n, 2] = nz.pos_px * mpp
            out_geom[n, 3] = nz.heading_px * mpp / kin.pattern_span
            out_geom[n, 4] = bx
            out_geom[n, 5] = by
            out_geom[n, 6] = th
            n += 1
    return n
