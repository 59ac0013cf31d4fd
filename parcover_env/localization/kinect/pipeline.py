"""Marker-based robot localization from overhead Kinect frames (Min et al. section IV, Figs. 7 and 9).

Pipeline, as in the paper: median filter (3x3) -> threshold (fixed; Otsu optional) -> morphology with
a 3x3 element (opening: removes projector speckle) then a 5x5 element (closing: fills holes) ->
marker blobs -> grouping of the blobs into robots -> convex hull of a robot's markers used as a mask
on the depth frame -> mean depth inside -> back-projection through the camera -> world pose.

Grouping and heading (our completion of the paper, which does not detail them): blob centroids are
intersected with the marker plane (robot height) and linked when closer than ``link_dist``; a group
of more than 4 blobs (robots touching) is split greedily into the subsets that best fit the marker
pattern. The pose is the rigid 2-D fit (all blob-to-marker assignments tried) of the known kite
pattern to the marker points, those being intersected with the horizontal plane at the height given
by the hull's mean depth. A fit with residual above ``max_residual`` is rejected.

:func:`~parcover_env.localization.kinect.estimate_model.estimate_fast` is a cheap statistical
stand-in for the full pipeline (see its docstring) and
:class:`~parcover_env.localization.kinect.tracker.KinectTracker` fuses several Kinects and keeps
identities across frames.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from parcover_env.geometry import wrap_angle
from parcover_env.geometry.camera import CameraModel
from parcover_env.sensors.kinect import KinectFrame, marker_pattern

__all__ = ["PipelineParams", "PoseEstimate", "pipeline_stages", "detect_markers", "find_blobs", "group_blobs",
           "fit_pattern", "estimate_poses"]


@dataclass(frozen=True)
class PipelineParams:
    """Parameters of the marker pipeline. ``marker_height`` = robot top (m); pattern from radius."""

    marker_height: float = 0.3
    robot_radius: float = 0.15
    median_ksize: int = 3
    threshold: int = 200
    otsu: bool = False
    otsu_floor: int = 150
    """With ``otsu``, the Otsu threshold is raised to at least this (speckle-only frames stay empty)."""
    open_ksize: int = 3
    close_ksize: int = 5
    min_area: int = 4
    max_area_frac: float = 0.01
    link_dist: float | None = None
    """Blob linking distance (m); None = 1.1 x the pattern's diameter (links a robot's markers even
    with one missed; touching robots then share a component, split by pattern fitting)."""
    marker_radius: float = 0.02
    max_residual: float = 0.015
    min_markers: int = 3

    def __post_init__(self) -> None:
        for k in ("median_ksize", "open_ksize", "close_ksize"):
            v = getattr(self, k)
            if v < 1 or v % 2 == 0:
                raise ValueError(f"PipelineParams.{k} must be an odd integer >= 1, got {v}")
        if not 0 <= self.threshold <= 255:
            raise ValueError(f"PipelineParams.threshold must be in [0, 255], got {self.threshold}")
        if not 3 <= self.min_markers <= 4:
            raise ValueError(f"PipelineParams.min_markers must be 3 or 4, got {self.min_markers}")
        if self.marker_height < 0 or self.robot_radius <= 0 or (self.link_dist or 1.0) <= 0:
            raise ValueError("PipelineParams: need marker_height >= 0, robot_radius > 0, link_dist > 0")
        marker_pattern(self.robot_radius, self.marker_radius)

    @property
    def pattern(self) -> np.ndarray:
        return marker_pattern(self.robot_radius, self.marker_radius)

    @property
    def link(self) -> float:
        """Effective blob linking distance (m)."""
        if self.link_dist is not None:
            return self.link_dist
        pat = self.pattern
        return 1.1 * float(np.linalg.norm(pat[:, None] - pat[None], axis=-1).max())


@dataclass(frozen=True)
class PoseEstimate:
    """A robot pose seen by one Kinect (world metres / radians) with diagnostics."""

    x: float
    y: float
    theta: float
    n_markers: int
    depth: float = float("nan")
    """Mean depth inside the marker hull (m); NaN on the fast path."""
    residual: float = 0.0
    """RMS of the marker-pattern fit (m)."""
    kinect: str = ""
    stamp: float = 0.0
    truth_index: int | None = None
    """Fast path only: index of the robot it was sampled from (do not use for association)."""

    @property
    def pose(self) -> np.ndarray:
        return np.array([self.x, self.y, self.theta])


def _check_ir(ir) -> np.ndarray:
    ir = np.asarray(ir)
    if ir.ndim != 2 or ir.dtype != np.uint8:
        raise ValueError(f"IR frame must be a 2-D uint8 array, got {ir.dtype} {ir.shape}")
    return ir


def pipeline_stages(ir, params: PipelineParams | None = None) -> dict[str, np.ndarray]:
    """The four images of Fig. 7: ``raw``, ``median``, ``threshold``, ``morphology`` (uint8)."""
    p = params or PipelineParams()
    ir = _check_ir(ir)
    with _one_cv_thread():
        med = cv2.medianBlur(ir, p.median_ksize) if p.median_ksize > 1 else ir.copy()
        if p.otsu:
            otsu, _ = cv2.threshold(med, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
            thr = max(float(otsu), float(p.otsu_floor))
        else:
            thr = float(p.threshold)
        _, binary = cv2.threshold(med, thr, 255, cv2.THRESH_BINARY)  # 255 where med > thr
        opened = cv2.morphologyEx(binary, cv2.MORPH_OPEN, np.ones((p.open_ksize, p.open_ksize), np.uint8))
        closed = cv2.morphologyEx(opened, cv2.MORPH_CLOSE, np.ones((p.close_ksize, p.close_ksize), np.uint8))
    return {"raw": ir, "median": med, "threshold": binary, "morphology": closed}


@contextlib.contextmanager
def _one_cv_thread():
    """OpenCV on one thread for the block: on a 320 x 240 frame its thread pool costs more than it
    gains (wall and CPU time of :func:`estimate_poses` both drop); the caller's setting is restored."""
    n = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(n)


def find_blobs(ir, params: PipelineParams | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Marker blobs: centroids ``(M, 2)`` (u, v px), pixel-label image, and the blobs' labels ``(M,)``,
    in raster order of the centroids (row ``v``, then column ``u``).

    Blobs touching the image border (cut markers, biased centroids) and blobs outside the area
    limits are discarded.
    """
    blobs = _blobs(ir, params or PipelineParams())
    labels = np.zeros(np.shape(ir), np.int32)
    (u0, v0), win = blobs.origin, blobs.labels
    labels[v0:v0 + win.shape[0], u0:u0 + win.shape[1]] = win
    return blobs.centroids, labels, blobs.ids


@dataclass(frozen=True)
class _Blobs:
    """Blobs of one IR frame, labelled on the smallest window holding every marker pixel."""

    centroids: np.ndarray
    """``(M, 2)`` image px (u, v) of the kept blobs."""
    labels: np.ndarray
    """Pixel labels of the window (0 = background)."""
    origin: tuple[int, int]
    """Image px (u0, v0) of the window's top-left pixel."""
    ids: np.ndarray
    """``(M,)`` labels of the kept blobs."""
    boxes: np.ndarray
    """``(M, 4)`` window px (u0, v0, u1, v1) of the kept blobs (exclusive ends)."""


def _blobs(ir, p: PipelineParams) -> _Blobs:
    """:func:`find_blobs` on the window: the same blobs, stats and centroids as on the whole image
    (the label numbers may differ: OpenCV numbers them in the order of its block scan, which depends
    on the window and on its thread count, hence the blobs are sorted by centroid). The centroids are
    shifted through their exact integer pixel sums (OpenCV divides the sum of the coordinates by
    the area), so they too equal the whole image's bit for bit."""
    mask = pipeline_stages(ir, p)["morphology"]
    h, w = mask.shape
    rows = np.flatnonzero(mask.any(axis=1))
    if len(rows) == 0:
        return _Blobs(np.zeros((0, 2)), np.zeros((0, 0), np.int32), (0, 0), np.zeros(0, int), np.zeros((0, 4), int))
    cols = np.flatnonzero(mask.any(axis=0))
    u0, v0 = int(cols[0]), int(rows[0])
    with _one_cv_thread():
        _, labels, stats, cents = cv2.connectedComponentsWithStats(
            mask[v0:int(rows[-1]) + 1, u0:int(cols[-1]) + 1], connectivity=8)
    x, y, bw, bh, area = (stats[1:, k] for k in range(5))
    keep = (area >= p.min_area) & (area <= p.max_area_frac * h * w)
    keep &= (x + u0 > 0) & (y + v0 > 0) & (x + u0 + bw < w) & (y + v0 + bh < h)
    ids = np.flatnonzero(keep) + 1
    a = stats[ids, cv2.CC_STAT_AREA].astype(float)
    sums = np.rint(cents[ids] * a[:, None]) + a[:, None] * (u0, v0)
    boxes = np.column_stack([x, y, x + bw, y + bh])[ids - 1]
    cents = sums / a[:, None]
    order = np.lexsort((cents[:, 0], cents[:, 1]))  # OpenCV's label order depends on its block scan and threads
    return _Blobs(cents[order], labels, (u0, v0), ids[order], boxes[order])


def detect_markers(ir, params: PipelineParams | None = None) -> np.ndarray:
    """Centroids ``(M, 2)`` (u, v pixels) of the marker blobs of an IR frame."""
    return find_blobs(ir, params)[0]


@functools.cache
def _assignments(n: int, m: int) -> np.ndarray:
    """Every injective assignment of ``n`` points to ``m`` markers, ``(P, n)`` (read-only, cached)."""
    out = np.array(list(itertools.permutations(range(m), n)), dtype=int).reshape(-1, n)
    out.setflags(write=False)
    return out


def fit_pattern(points, pattern) -> tuple[np.ndarray, float, np.ndarray]:
    """Best rigid 2-D fit of ``pattern (4, 2)`` (robot frame) to observed ``points (n, 2)``, n in 2..4.

    Every injective assignment of points to pattern markers is tried. Returns the pose
    ``(x, y, theta)`` of the robot frame, the fit's RMS residual (m) and the assignment ``(n,)``.
    """
    pts = np.asarray(points, dtype=float)
    pat = np.asarray(pattern, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or not 2 <= len(pts) <= len(pat):
        raise ValueError(f"fit_pattern needs 2..{len(pat)} points of shape (n, 2), got {pts.shape}")
    perms, mc, a, aa = _centred_models(pat.tobytes(), len(pat), len(pts))
    n = len(pts)
    oc = pts.mean(axis=0)
    b = pts - oc
    cross = a[..., 0] @ b[:, 1] - a[..., 1] @ b[:, 0]
    dot = a[..., 0] @ b[:, 0] + a[..., 1] @ b[:, 1]
    # best rotation of each assignment: the angle of (dot, cross); its residual sum of squares is
    # |a|^2 + |b|^2 - 2 |(dot, cross)| (the rotated model's cross term at its maximum)
    rss = aa + float((b * b).sum()) - 2.0 * np.hypot(cross, dot)
    rms = np.sqrt(np.maximum(rss, 0.0) / n)
    k = int(np.argmin(rms))
    th = math.atan2(cross[k], dot[k])
    ck, sk, (mx, my) = math.cos(th), math.sin(th), mc[k]
    t = oc - np.array([ck * mx - sk * my, sk * mx + ck * my])
    return np.array([t[0], t[1], float(wrap_angle(th))]), float(rms[k]), perms[k]


@functools.lru_cache(maxsize=64)
def _centred_models(pattern: bytes, m: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For every assignment of ``n`` points to the ``m`` markers of ``pattern`` (float64 bytes):
    the assignments ``(P, n)``, the assigned markers' centroid ``(P, 2)``, the markers about it
    ``(P, n, 2)`` and their sum of squares ``(P,)`` (cached: the pattern is fixed)."""
    pat = np.frombuffer(pattern, dtype=float).reshape(m, 2)
    perms = _assignments(n, m)
    model = pat[perms]
    mc = model.mean(axis=1)
    a = model - mc[:, None]
    return perms, mc, a, (a * a).sum(axis=(1, 2))


def group_blobs(points, params: PipelineParams | None = None) -> list[np.ndarray]:
    """Group marker points ``(M, 2)`` (world xy on the marker plane) into robots: index arrays.

    Single-linkage within ``link_dist``; components of more than 4 points are split greedily into
    the 4- (then 3-) subsets that best fit the pattern. Groups under ``min_markers`` are dropped.
    """
    p = params or PipelineParams()
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    m = len(pts)
    if m == 0:
        return []
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    n_comp, comp = _components(d <= p.link)
    groups: list[np.ndarray] = []
    for c in range(n_comp):
        idx = np.flatnonzero(comp == c)
        if len(idx) <= 4:
            groups.append(idx)
            continue
        left = list(idx)
        while len(left) >= p.min_markers:
            best = None
            for size in (4, 3):
                if size < p.min_markers or size > len(left):
                    continue
                for sub in itertools.combinations(left, size):
                    _, rms, _ = fit_pattern(pts[list(sub)], p.pattern)
                    if best is None or rms < best[0]:
                        best = (rms, sub)
                if best is not None and best[0] <= p.max_residual:
                    break
            if best is None or best[0] > p.max_residual:
                break
            groups.append(np.array(sorted(best[1])))
            left = [i for i in left if i not in best[1]]
    return [g for g in groups if len(g) >= p.min_markers]


def _components(adj: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of the undirected graph ``adj (M, M) bool``: their number and each
    node's component, numbered in the order of their lowest node (as scipy's ``connected_components``
    numbers them; a search over a few blobs costs microseconds instead of scipy's input checks)."""
    m = len(adj)
    comp = np.full(m, -1, dtype=np.int32)
    n = 0
    for start in range(m):
        if comp[start] >= 0:
            continue
        comp[start] = n
        todo = [start]
        while todo:
            for j in np.flatnonzero(adj[todo.pop()] & (comp < 0)).tolist():
                comp[j] = n
                todo.append(j)
        n += 1
    return n, comp


def estimate_poses(frame: KinectFrame, camera: CameraModel,
                   params: PipelineParams | None = None) -> list[PoseEstimate]:
    """Poses of the marker-carrying robots in one frame (full pipeline of the paper)."""
    p = params or PipelineParams()
    if frame.dropped:
        return []
    depth = np.asarray(frame.depth)
    if depth.shape != (camera.height, camera.width) or np.asarray(frame.ir).shape != depth.shape:
        raise ValueError(f"frame shape {depth.shape} does not match the camera "
                         f"({camera.height}, {camera.width})")
    blobs = _blobs(frame.ir, p)
    cents, ids, boxes = blobs.centroids, blobs.ids, blobs.boxes
    if len(cents) < p.min_markers:
        return []
    approx, _ = camera.intersect_plane(cents, p.marker_height)
    ok = np.all(np.isfinite(approx), axis=1)
    cents, ids, boxes, approx = cents[ok], ids[ok], boxes[ok], approx[ok]
    out = []
    for g in group_blobs(approx[:, :2], p):
        # the hull of the group's marker pixels, drawn in the box around its blobs (window px)
        bu0, bv0 = boxes[g, :2].min(axis=0)
        bu1, bv1 = boxes[g, 2:].max(axis=0)
        window = blobs.labels[bv0:bv1, bu0:bu1]
        mask = np.zeros(window.shape, np.uint8)
        for i in ids[g].tolist():  # a few blobs: cheaper than np.isin's set machinery
            mask[window == i] = 1
        hull = cv2.convexHull(cv2.findNonZero(mask))
        hull_mask = np.zeros(mask.shape, np.uint8)
        cv2.fillConvexPoly(hull_mask, hull, 1)
        vv, uu = np.nonzero(hull_mask)
        vv, uu = vv + (bv0 + blobs.origin[1]), uu + (bu0 + blobs.origin[0])
        z = depth[vv, uu]
        valid = z > 0
        if not np.any(valid):
            continue  # the paper's failure case: no depth at all inside the hull
        z_mean = float(z[valid].mean())
        centre_uv = np.array([[uu.mean(), vv.mean()]])
        plane_z = float(camera.backproject(centre_uv, np.array([z_mean]))[0, 2])
        marks, _ = camera.intersect_plane(cents[g], plane_z)
        if not np.all(np.isfinite(marks)):
            continue
        pose, rms, _ = fit_pattern(marks[:, :2], p.pattern)
        if rms > p.max_residual:
            continue
        out.append(PoseEstimate(float(pose[0]), float(pose[1]), float(pose[2]), len(g), z_mean, rms,
                                frame.name, frame.stamp))
    return out
