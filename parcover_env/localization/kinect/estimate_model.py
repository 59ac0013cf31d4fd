"""The Kinect *estimate* model: a cheap statistical stand-in for rendering frames and running the
marker pipeline (:func:`~parcover_env.localization.kinect.pipeline.estimate_poses`), used by
``kinect: estimate``. All due Kinects go through one compiled call
(:func:`~parcover_env.localization.kinect.estimate_kernel.estimate`) with their constants stacked
once per mounting (:class:`FastModel`).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from parcover_env.geometry.records import record, table
from parcover_env.localization.kinect import estimate_kernel
from parcover_env.localization.kinect.pipeline import PoseEstimate
from parcover_env.sensors.kinect import NATIVE_WIDTH, KinectSensor, check_poses

__all__ = ["FastNoise", "FastModel", "estimate_fast", "estimate_fast_all", "view_box"]


@dataclass(frozen=True)
class FastNoise:
    """Error model of the fast path, calibrated with ``benchmarks/kinect_accuracy.py`` on the full
    pipeline (Kinect looking down, 2.8-3.0 m). Errors are Gaussian with per-axis position std
    ``pos_px`` and heading std ``heading_px / span`` in pixels at the robot's depth (metres = px * z / f),
    both times ``(640 / width) ** res_exponent``. Detection probability ramps linearly from 0 to 1
    as the marker radius in pixels goes from ``r_px_min`` to ``r_px_full`` (small markers vanish in
    the 3x3 opening)."""

    pos_px: float = 0.05
    heading_px: float = 0.10
    res_exponent: float = 1.3
    r_px_min: float = 1.95
    r_px_full: float = 2.35
    margin_px: float = 2.0


def estimate_fast(sensor: KinectSensor, poses, marker_mask, rng: np.random.Generator,
                  noise: FastNoise | None = None, stamp: float = 0.0) -> list[PoseEstimate]:
    """Cheap stand-in for render + :func:`~parcover_env.localization.kinect.pipeline.estimate_poses`:
    visibility test plus sampled errors.

    A marker-carrying robot is detected when every marker disc projects inside the image (with a
    margin), its depth is within the valid range and no wall top hides it (static depth); frames are
    dropped at ``drop_rate``. The estimate is the true pose plus Gaussian noise whose scale
    (``noise``, in pixels) was measured on the full pipeline, so both paths agree statistically.
    """
    return estimate_fast_all([sensor], poses, marker_mask, rng, noise, stamp)[0]


def estimate_fast_all(sensors: list[KinectSensor], poses, marker_mask, rng: np.random.Generator,
                      noise: FastNoise | None = None, stamp: float = 0.0) -> list[list[PoseEstimate]]:
    """:func:`estimate_fast` of each sensor in turn, the inputs checked once: the same estimates
    from the same random draws in the same order as one call per sensor."""
    if not sensors:
        return []
    poses, mask = check_poses(poses, marker_mask)
    return FastModel(sensors, noise).estimate(range(len(sensors)), poses, mask, rng, stamp)


class FastModel:
    """The estimate model (:func:`estimate_fast`) of a set of Kinects: their constants stacked once
    (a :data:`~parcover_env.localization.kinect.estimate_kernel.KINECT` row per Kinect) for one
    compiled call per step. Build it again after a sensor is remounted; do not rebind its tables after its
    first step (the batched worlds' stacked tables are kept by model)."""

    def __init__(self, sensors: list[KinectSensor], noise: FastNoise | None = None):
        self.sensors = list(sensors)
        nz = noise or FastNoise()
        self.kinects = table(estimate_kernel.KINECT, [_row(s, nz) for s in self.sensors])
        """Per Kinect: cameras, image size, markers, range and drop rate."""
        self.pattern = np.stack([np.asarray(s.pattern, dtype=float) for s in self.sensors])
        """``(S, K, 2)`` each Kinect's marker pattern (robot frame, m)."""
        self.depths = tuple(np.ascontiguousarray(s.nominal_static_depth, dtype=float) for s in self.sensors)
        """Each Kinect's static depth through its nominal camera (the wall-occlusion test)."""
        self.noise = record(estimate_kernel.FAST_NOISE, margin_px=nz.margin_px, close_px=_CLOSE_KSIZE - 2,
                            r_px_min=nz.r_px_min, r_px_full=nz.r_px_full, pos_px=nz.pos_px, heading_px=nz.heading_px)

    def estimate(self, due, poses: np.ndarray, mask: np.ndarray, rng: np.random.Generator,
                 stamp: float = 0.0) -> list[list[PoseEstimate]]:
        """Estimates of the Kinects ``due`` (indices into ``sensors``, in that order) of the
        marker carriers ``mask`` among the checked true ``poses (N, 3)``: one list per Kinect."""
        due = np.asarray(due, dtype=np.int64).reshape(-1)
        carriers = np.flatnonzero(mask)
        cap = len(due) * len(carriers)
        out_sensor, out_index, out_pose = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty((cap, 3))
        n = estimate_kernel.estimate(due, np.ascontiguousarray(poses, dtype=float), carriers, self.kinects,
                                     self.pattern, self.depths, self.noise, rng, out_sensor, out_index, out_pose)
        per: list[list[PoseEstimate]] = [[] for _ in due]
        k = self.pattern.shape[1]
        for p, i, (x, y, th) in zip(out_sensor[:n].tolist(), out_index[:n].tolist(), out_pose[:n].tolist(),
                                    strict=True):
            per[p].append(PoseEstimate(x, y, th, k, kinect=self.sensors[due[p]].name, stamp=stamp, truth_index=i))
        return per


_CLOSE_KSIZE = 5
"""The pipeline's closing kernel (px): markers whose gap is under ``_CLOSE_KSIZE - 2`` px merge
(gaps of >= 3 px keep at least 3 markers apart in the full pipeline: checked on ``tree``)."""


def _row(s: KinectSensor, nz: FastNoise) -> dict:
    """The :data:`~parcover_env.localization.kinect.estimate_kernel.KINECT` row of one sensor."""
    true, nominal = s.true_camera, s.camera
    box = view_box(s)
    return dict(box=box if box is not None else (0.0,) * 4, use_box=box is not None,
                R=true.R, C=true.C, K=_intrinsics(true), nominal_R=nominal.R, nominal_C=nominal.C,
                nominal_K=_intrinsics(nominal), remounted=true is not nominal, width=s.shape[1], height=s.shape[0],
                marker_radius=s.marker_radius, marker_height=s.robot_height, range_min=true.range_min,
                range_max=true.range_max, drop_rate=s.cfg.drop_rate, pattern_gap=_pattern_gap(s),
                res_scale=(NATIVE_WIDTH / s.shape[1]) ** nz.res_exponent,
                pattern_span=float(np.ptp(s.pattern[:, 0])) or 0.1)


def _intrinsics(cam) -> tuple[float, float, float, float]:
    """``(fu, fv, cu, cv)`` of a camera (px)."""
    return cam.K[0, 0], cam.K[1, 1], cam.K[0, 2], cam.K[1, 2]


_STATIC: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Static per-sensor quantities of the fast path (see ``_sensor_cache``)."""


def _sensor_cache(sensor: KinectSensor) -> dict:
    """Per-sensor cache of static quantities, dropped if the camera, pattern or height change."""
    cam, key = sensor.true_camera, (sensor.pattern.tobytes(), sensor.marker_radius, sensor.robot_height)
    entry = _STATIC.get(sensor)
    if entry is None or entry[0] is not cam or entry[1] != key:  # the camera itself, not its id (reused)
        entry = (cam, key, {})
        _STATIC[sensor] = entry
    return entry[2]


def _pattern_gap(sensor: KinectSensor) -> float:
    """Smallest edge-to-edge distance between two markers of the pattern (m)."""
    cache = _sensor_cache(sensor)
    if "gap" not in cache:
        pat = sensor.pattern
        d = np.linalg.norm(pat[:, None] - pat[None], axis=-1) + np.eye(len(pat)) * 1e9
        cache["gap"] = float(d.min()) - 2 * sensor.marker_radius
    return cache["gap"]


def view_box(sensor: KinectSensor) -> tuple[float, float, float, float] | None:
    """Floor box ``(x0, y0, x1, y1)`` outside which no robot centre can have all its markers in the
    image: the image corners cast onto the marker plane, grown by the pattern's reach (1 mm slack).
    None when a corner ray does not meet that plane (a tilted camera): no pre-filter then."""
    cache = _sensor_cache(sensor)
    if "box" not in cache:
        cam = sensor.true_camera
        corners = np.array([[0.0, 0.0], [cam.width - 1.0, 0.0], [cam.width - 1.0, cam.height - 1.0],
                            [0.0, cam.height - 1.0]])
        rays = cam.pixel_rays(corners)
        box = None
        if np.all(rays[:, 2] < 0) and sensor.robot_height < cam.C[2]:
            t = (sensor.robot_height - cam.C[2]) / rays[:, 2]
            pts = cam.C[:2] + t[:, None] * rays[:, :2]
            reach = float(np.hypot(sensor.pattern[:, 0], sensor.pattern[:, 1]).max()) + 1e-3
            lo, hi = pts.min(axis=0) - reach, pts.max(axis=0) + reach
            box = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
        cache["box"] = box
    return cache["box"]
