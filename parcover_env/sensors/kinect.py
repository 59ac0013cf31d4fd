"""Synthetic overhead Kinect v1: a depth frame and an IR frame rendered from ground truth.

Model (Min et al. section III-A/IV, ALGORITHMS.md "Kinect v1 model"):

* Scene: the floor (z = 0), every non-free region of the map extruded to ``wall_height`` (walls,
  obstacles, outside of the building), and robots as vertical cylinders of radius ``r`` and
  height ``h`` (top disc at ``h``). The static part is rendered once in ``__init__``.
* Markers: 4 retro-reflective discs (radius ``marker_radius``) on each marker-carrying robot's top,
  in the asymmetric quadrilateral of :func:`marker_pattern` (robot frame, x forward, for r >= 0.13 m):
  ``(0.105, 0)`` front, ``(0.03, 0.09)`` front-left, ``(-0.095, 0.05)`` back-left, ``(0.03, -0.065)``
  right; smaller robots get it shrunk so the discs stay on the top. It was chosen by a search so
  that no wrong assignment of 3 or 4 markers fits it better than 2 cm RMS (heading unique even
  with one marker missed; a symmetric kite has a near-equilateral 3-subset) and markers are
  >= 10 cm apart, so the pipeline's 5x5 closing does not merge them.
* Depth: camera z (m), float32, 0 = invalid. Axial noise sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2
  (Nguyen et al. 2012), then disparity d = f b / z rounded to 1/8 px (f of the native 640-wide
  sensor, b = 0.075 m), then the range limits (outside [range_min, range_max] -> 0). Depth is
  missing (0) where the markers saturate the IR image (plus ``missing_factor`` margin).
* IR: uint8. Dull floor (55), wall (40) and robot (75) levels plus uniform noise (0-31),
  projector speckle (isolated bright pixels and a few small bright clusters), saturated (255)
  marker blobs.

* Lateral noise: each depth pixel reads the depth ``N(0, lateral_noise_px)`` pixels away
  (rounded, per axis), which frays depth edges and the marker holes (Nguyen et al.: ~0.8 px).
* Mounting error (:meth:`KinectSensor.mount`, once per episode from the episode RNG): the camera
  hangs off its nominal pose by ``N(0, mount_tilt_std_deg)`` in pitch and roll,
  ``N(0, mount_yaw_std_deg)`` about its optical axis and ``N(0, mount_height_std)`` in height.
  Frames are rendered by that *true* camera (``true_camera``); ``camera`` stays the nominal one the
  localization pipeline uses, so every fix carries the mounting error (1 deg at 2.5 m ~ 4 cm).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from parcover_env.geometry import cast_rays
from parcover_env.geometry.camera import CameraModel
from parcover_env.geometry.records import record
from parcover_env.sensors.kinect_noise import axial_sigma, normal_table, rounded_normal_table

if TYPE_CHECKING:
    from parcover_env.config import KinectConfig
    from parcover_env.world.map_model import MapModel

__all__ = ["KinectFrame", "KinectSensor", "marker_pattern", "axial_sigma", "may_see_all", "check_poses",
           "normal_table", "rounded_normal_table", "BASELINE", "NATIVE_WIDTH"]

BASELINE = 0.075
"""Projector-camera baseline b of the Kinect v1 (m)."""
NATIVE_WIDTH = 640
"""Disparity is computed by the device at 640 px width, whatever the output resolution."""
_NORMAL_BITS = 12
"""Resolution of the axial noise's standard-normal draws (see :meth:`KinectSensor.noisy_depth`)."""
_UNIT_PATTERN = np.array([[0.105, 0.0], [0.03, 0.09], [-0.095, 0.05], [0.03, -0.065]])


def marker_pattern(robot_radius: float = 0.15, marker_radius: float = 0.02) -> np.ndarray:
    """Marker centres ``(4, 2)`` in the robot frame (m): a kite, shrunk to fit small robots' tops."""
    if not robot_radius > marker_radius > 0:
        raise ValueError(f"need robot_radius > marker_radius > 0, got {robot_radius}, {marker_radius}")
    return _UNIT_PATTERN * min(1.0, (robot_radius - marker_radius) / 0.108)


@dataclass
class KinectFrame:
    """One Kinect measurement. ``depth`` (H, W) float32 m (0 = invalid), ``ir`` (H, W) uint8."""

    name: str
    depth: np.ndarray
    ir: np.ndarray
    stamp: float = 0.0
    dropped: bool = False
    info: dict = field(default_factory=dict)


_NOMINAL_STATIC: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Static scenes through nominal cameras: map model -> {(KinectConfig, wall height): (depth, class, IR)}."""


class KinectSensor:
    """Overhead Kinect rendering depth + IR frames of robots on a static map.

    Everything static (pixel rays, the depth and surface class of the empty scene) is computed once
    here; :meth:`measure` only re-renders the image boxes around the robots and draws the noise.
    """

    FLOOR, WALL = 0, 1

    def __init__(self, cfg: KinectConfig, robot_radius: float, robot_height: float, map_model: MapModel,
                 wall_height: float = 0.5, marker_radius: float = 0.02, missing_factor: float = 1.5,
                 speckle_density: float = 0.03, speckle_clusters: int = 40):
        if not robot_radius > 0 or not robot_height > 0:
            raise ValueError(f"robot radius and height must be > 0, got {robot_radius}, {robot_height}")
        if not wall_height > 0 or not marker_radius > 0 or missing_factor < 1:
            raise ValueError("wall_height and marker_radius must be > 0 and missing_factor >= 1")
        if not 0 <= speckle_density < 0.5:
            raise ValueError(f"speckle_density must be in [0, 0.5), got {speckle_density}")
        self.cfg = cfg
        self.name = cfg.name
        self.camera = CameraModel.from_config(cfg)
        """Nominal camera: what the localization pipeline believes (intrinsics + extrinsics)."""
        self.true_camera = self.camera
        """Camera as mounted this episode (:meth:`mount`); renders the frames."""
        self._map_model = map_model
        if robot_height >= self.camera.C[2]:
            raise ValueError(f"Kinect '{cfg.name}' at {self.camera.C[2]} m is not above the robots "
                             f"({robot_height} m)")
        self.robot_radius = float(robot_radius)
        self.robot_height = float(robot_height)
        self.wall_height = float(wall_height)
        self.marker_radius = float(marker_radius)
        self.missing_factor = float(missing_factor)
        self.speckle_density = float(speckle_density)
        self.speckle_clusters = int(speckle_clusters)
        self.pattern = marker_pattern(robot_radius, marker_radius)
        w, h = self.camera.width, self.camera.height
        self.shape = (h, w)
        self._lateral: np.ndarray | None = None
        self._box_ring: np.ndarray | None = None
        self._buffers: dict[str, np.ndarray] = {}
        """Work images of :meth:`measure` that never leave it, kept from frame to frame: a fresh
        image of this size costs its page faults again at every frame."""
        self.fb = self.camera.focal * (NATIVE_WIDTH / w) * BASELINE
        self._view_of(self.true_camera)
        self.nominal_static_depth = self.static_depth
        """Depth of the empty scene through the nominal camera (rendered once; the fast path's
        wall-occlusion test uses it: a mounting error moves it by a pixel or two)."""

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_buffers"] = {}  # work images: not part of the state
        return state

    def _buffer(self, name: str, dtype) -> np.ndarray:
        """The work image ``name`` (frame-sized, uninitialized)."""
        buf = self._buffers.get(name)
        if buf is None or buf.shape != self.shape or buf.dtype != dtype:
            buf = self._buffers[name] = np.empty(self.shape, dtype=dtype)
        return buf

    def _view_of(self, camera: CameraModel) -> None:
        """Look through ``camera`` (the true one): its pixel rays and static scene are computed when
        first needed (the estimate model needs neither, so a reset's mounting allocates nothing)."""
        self._ray_camera = camera
        self._rays: np.ndarray | None = None
        self._cull = None
        self._static = None

    @property
    def rays(self) -> np.ndarray:
        """World-frame ray direction ``(H, W, 3)`` of every pixel of the true camera."""
        if self._rays is None:
            h, w = self.shape
            uu, vv = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
            self._rays = self._ray_camera.pixel_rays(np.stack([uu.ravel(), vv.ravel()], axis=1)).reshape(h, w, 3)
        return self._rays

    def _static_scene(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._static is None:
            nominal = self.true_camera is self.camera
            key = (self.cfg, self.wall_height)
            cache = _NOMINAL_STATIC.setdefault(self._map_model, {}) if nominal else {}
            if key not in cache:  # the nominal scene is rendered once per map and Kinect per process
                depth, cls = self._render_static(self._map_model)
                ir = np.where(cls == self.WALL, 40, 55).astype(np.int16)
                for a in (depth, cls, ir):
                    a.setflags(write=False)  # shared between sensors: every user copies before drawing
                cache[key] = (depth, cls, ir)
            self._static = cache[key]
        return self._static

    @property
    def static_depth(self) -> np.ndarray:
        """Camera depth of the empty scene through the true camera (inf where nothing is met)."""
        return self._static_scene()[0]

    @property
    def static_class(self) -> np.ndarray:
        """Surface class (``FLOOR`` / ``WALL``) of the empty scene through the true camera."""
        return self._static_scene()[1]

    @property
    def _static_ir(self) -> np.ndarray:
        return self._static_scene()[2]

    def mount(self, rng: np.random.Generator) -> None:
        """Draw this episode's mounting error (see the module notes). Without mounting errors in
        the config nothing is drawn and the camera stays nominal."""
        cfg = self.cfg
        if cfg.mount_tilt_std_deg == 0 and cfg.mount_yaw_std_deg == 0 and cfg.mount_height_std == 0:
            if self.true_camera is not self.camera:
                self.true_camera = self.camera
                self._view_of(self.camera)
            return
        tilt, yaw = math.radians(cfg.mount_tilt_std_deg), math.radians(cfg.mount_yaw_std_deg)
        e = rng.standard_normal(4) * np.array([tilt, tilt, yaw, cfg.mount_height_std])
        self.true_camera = self.camera.perturbed(*e.tolist())
        self._view_of(self.true_camera)  # the true static scene is rendered only if frames are

    # ------------------------------------------------------------------ static scene
    def _render_static(self, map_model: MapModel) -> tuple[np.ndarray, np.ndarray]:
        """Camera depth of the empty scene (inf where the ray never meets it) and surface class."""
        h, w = self.shape
        rays = self.rays.reshape(-1, 3)
        C = self.true_camera.C
        dz = rays[:, 2]
        down = dz < -1e-12
        with np.errstate(divide="ignore", invalid="ignore"):
            t_floor = np.where(down, -C[2] / dz, np.inf)
        depth = t_floor.copy()
        cls = np.full(len(rays), self.FLOOR, dtype=np.uint8)
        if C[2] > self.wall_height:
            with np.errstate(divide="ignore", invalid="ignore"):
                t0 = np.where(down, (self.wall_height - C[2]) / dz, np.inf)
            idx = np.flatnonzero(down)
            p_top = C[:2] + rays[idx, :2] * t0[idx, None]
            solid = ~map_model.contains(p_top)
            depth[idx[solid]] = t0[idx[solid]]
            cls[idx[solid]] = self.WALL
            idx = idx[~solid]
        else:
            t0 = np.zeros(len(rays))
            idx = np.flatnonzero(down)
        # The ray descends through free air from t0 to the floor: first vertical wall face it meets.
        seg = map_model.segments
        for start in range(0, len(idx), 4096):
            sel = idx[start:start + 4096]
            a = C[:2] + rays[sel, :2] * t0[sel, None]
            b = C[:2] + rays[sel, :2] * t_floor[sel, None]
            span = np.linalg.norm(b - a, axis=1)
            moving = span > 1e-9
            if not np.any(moving):
                continue
            sel, a, b, span = sel[moving], a[moving], b[moving], span[moving]
            hits = cast_rays(a, (b - a) / span[:, None], seg, float(span.max()) + 1.0)
            dist, hit = hits.distance, hits.index
            wall = (hit >= 0) & (dist < span)
            frac = dist[wall] / span[wall]
            depth[sel[wall]] = t0[sel[wall]] + frac * (t_floor[sel[wall]] - t0[sel[wall]])
            cls[sel[wall]] = self.WALL
        return depth.reshape(h, w), cls.reshape(h, w)

    # ------------------------------------------------------------------ robots
    def _robot_boxes(self, centres: np.ndarray) -> np.ndarray:
        """Pixel boxes ``(N, 4)`` int (u0, v0, u1, v1; exclusive ends) covering each robot's
        cylinder, a row of -1 where it is behind the camera or outside the image; all robots
        projected in one call."""
        n = len(centres)
        boxes = np.full((n, 4), -1, dtype=np.int64)
        if n == 0:
            return boxes
        if self._box_ring is None:  # 16 points around the bottom and the top rim, a little outside
            ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
            ring = np.stack([np.cos(ang), np.sin(ang)], axis=1) * (self.robot_radius * 1.05)
            self._box_ring = np.zeros((2, 16, 3))
            self._box_ring[..., :2] = ring
            self._box_ring[1, :, 2] = self.robot_height
        pts = np.empty((n, 2, 16, 3))
        pts[...] = self._box_ring
        pts[..., :2] += centres[:, None, None, :]
        uv, z = self.true_camera.project(pts.reshape(-1, 3))
        uv, z = uv.reshape(n, 32, 2), z.reshape(n, 32)
        h, w = self.shape
        lo = np.maximum(np.floor(uv.min(axis=1)).astype(np.int64) - 1, 0)
        hi = np.minimum(np.ceil(uv.max(axis=1)).astype(np.int64) + 2, (w, h))
        ok = np.all(z > 1e-6, axis=1) & np.all(lo < hi, axis=1)
        boxes[ok, :2], boxes[ok, 2:] = lo[ok], hi[ok]
        return boxes

    def cull_box(self) -> tuple[float, float, float, float]:
        """Floor box outside which no robot cylinder can appear in the image (cached): the image
        corners cast on the floor and on the robot-top plane, grown by the robot radius. Config
        validation keeps every corner ray below the horizon, so both planes are met."""
        if getattr(self, "_cull", None) is None:
            cam = self.true_camera
            corners = np.array([[-0.5, -0.5], [cam.width - 0.5, -0.5], [cam.width - 0.5, cam.height - 0.5],
                                [-0.5, cam.height - 0.5]])
            rays = cam.pixel_rays(corners)
            pts = np.concatenate([cam.C[:2] + ((z - cam.C[2]) / rays[:, 2])[:, None] * rays[:, :2]
                                  for z in (0.0, self.robot_height)])
            grow = self.robot_radius * 1.05 + 1e-3
            lo, hi = pts.min(axis=0) - grow, pts.max(axis=0) + grow
            self._cull = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
        return self._cull

    def may_see(self, poses: np.ndarray, marker_mask: np.ndarray) -> bool:
        """Whether some marker carrier stands inside :meth:`cull_box` (cheap and conservative: a
        ``False`` means no frame of this camera can show a marker, so none needs rendering)."""
        return bool(may_see_all([self], poses, marker_mask)[0])

    def render_clean(self, poses: np.ndarray,
                     marker_mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Noise-free render: depth (inf = no surface), owner id (-1 = static), marker code.

        Marker code per pixel: 0 none, 1 saturated marker, 2 depth-missing halo only.
        """
        poses, marker_mask = check_poses(poses, marker_mask)
        return tuple(a.copy() for a in self._render_clean(poses, marker_mask))

    def _render_clean(self, poses: np.ndarray, marker_mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`render_clean` of checked inputs into the sensor's work images (valid until the
        next call)."""
        depth = self._buffer("depth", float)
        np.copyto(depth, self.static_depth)
        owner = self._buffer("owner", np.int32)
        owner.fill(-1)
        top = self._buffer("top", bool)
        top.fill(False)
        C = self.true_camera.C
        cx0, cy0, cx1, cy1 = self.cull_box()
        seen = np.flatnonzero((poses[:, 0] >= cx0) & (poses[:, 0] <= cx1) & (poses[:, 1] >= cy0)
                              & (poses[:, 1] <= cy1))
        boxes = np.full((len(poses), 4), -1, dtype=np.int64)  # u0 < 0: not drawn
        boxes[seen] = self._robot_boxes(poses[seen, :2])
        k = _kernels()
        k.draw_robots(depth, owner, top, self.rays, C, boxes, np.ascontiguousarray(poses[:, :2]),
                      self.robot_radius ** 2, self.robot_height)
        code = self._buffer("code", np.uint8)
        code.fill(0)
        carriers = np.flatnonzero(marker_mask & (boxes[:, 0] >= 0))
        if len(carriers):
            cos_sin = np.array([(math.cos(th), math.sin(th)) for th in poses[:, 2].tolist()])
            discs = record(k.MARKER_DISCS, marker_r2=self.marker_radius ** 2,
                           halo_r2=(self.marker_radius * self.missing_factor) ** 2)
            k.marker_codes(code, depth, owner, top, self.rays, C, boxes, poses, cos_sin, carriers, self.pattern, discs)
        return depth, owner, code

    # ------------------------------------------------------------------ measurement
    def lateral_jitter(self, depth: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Lateral noise: each pixel reads the depth ``round(N(0, lateral_noise_px))`` pixels away (per
        axis, clamped to the image). Applied to the noisy depth, which has the same distribution
        as noising the displaced clean depth; drawn after the IR frame.

        The offsets come from 16-bit uniform draws through the inverse CDF of the rounded normal
        (:func:`rounded_normal_table`): the same distribution up to 2**-16 per offset, at a
        fraction of the cost of drawing and rounding two normals per pixel."""
        if self.cfg.lateral_noise_px <= 0:
            return depth
        h, w = depth.shape
        if self._lateral is None:  # offsets of at most 8 sigma + 1 <= 41 px: int8 keeps the table in cache
            self._lateral = rounded_normal_table(self.cfg.lateral_noise_px).astype(np.int8)
        table = self._lateral
        draws = rng.integers(0, 1 << 16, size=(2, h, w), dtype=np.uint16)
        out = np.empty_like(depth)
        _kernels().lateral_shift(np.ascontiguousarray(depth), draws, table, out)
        return out

    def noisy_depth(self, depth: np.ndarray, rng: np.random.Generator, out: np.ndarray | None = None) -> np.ndarray:
        """Axial noise, 1/8-px disparity quantization and range limits applied to a clean depth.

        The standard-normal draw of each pixel is the top 12 bits of a 16-bit uniform integer
        through the normal's inverse CDF (:func:`normal_table`): a normal quantized to 4096 equally
        likely values (``|Z| <= 3.67``, variance 0.9997), at a fraction of the cost of a float draw
        per pixel (the 16 kB table stays in the processor's first-level cache; numpy draws whole
        16-bit words faster than 12-bit ones)."""
        draws = rng.integers(0, 1 << 16, size=depth.shape, dtype=np.uint16)
        out = np.empty(depth.shape, dtype=np.float32) if out is None else out
        cam = self.camera
        _kernels().depth_noise(np.ascontiguousarray(depth, dtype=float), draws, normal_table(_NORMAL_BITS),
                               16 - _NORMAL_BITS, np.float32(self.fb),
                               _as_f32_bound(cam.range_min), _as_f32_bound(cam.range_max), out)
        return out

    def render_ir(self, owner: np.ndarray, code: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """IR frame: dull surfaces with noise, projector speckle, saturated markers."""
        h, w = self.shape
        ir = np.empty((h, w), dtype=np.uint8)
        noise = rng.integers(0, 256, size=(h, w), dtype=np.uint8)
        _kernels().ir_levels(self._static_ir, owner, noise, 75, ir)  # at most 75 + 31: no overflow
        n = int(self.speckle_density * h * w)
        if n:
            idx = rng.integers(0, h * w, size=n)
            ir.reshape(-1)[idx] = rng.integers(170, 256, size=n, dtype=np.int16)
        if self.speckle_clusters:  # a few denser projector spots (2 x 3 px): survive median + threshold
            k = self.speckle_clusters
            vs, us = rng.integers(0, h - 2, size=k), rng.integers(0, w - 3, size=k)
            for dv in range(2):
                for du in range(3):
                    ir[vs + dv, us + du] = 255
        ir[code == 1] = 255
        return ir

    def measure(self, poses, marker_mask, rng: np.random.Generator, stamp: float = 0.0) -> KinectFrame:
        """Render one frame of robots at ``poses (N, 3)``; ``marker_mask (N,)``: who carries markers.

        With probability ``cfg.drop_rate`` the frame is dropped: ``dropped=True``, all-zero images.
        """
        poses, marker_mask = check_poses(poses, marker_mask)
        if self.cfg.drop_rate > 0 and rng.random() < self.cfg.drop_rate:
            return KinectFrame(self.name, np.zeros(self.shape, np.float32), np.zeros(self.shape, np.uint8),
                               stamp, dropped=True)
        depth, owner, code = self._render_clean(poses, marker_mask)
        noisy = self.noisy_depth(depth, rng, out=self._buffer("noisy", np.float32))
        ir = self.render_ir(owner, code, rng)
        z = self.lateral_jitter(noisy, rng)
        if z is noisy:  # no lateral noise: the frame gets its own image, not the work image
            z = noisy.copy()
        z[code > 0] = 0.0  # depth is missing exactly where the markers saturate the IR image
        return KinectFrame(self.name, z, ir, stamp, info={"n_robots": len(poses)})


def may_see_all(sensors: list[KinectSensor], poses, marker_mask) -> np.ndarray:
    """:meth:`KinectSensor.may_see` of each sensor ``(K,) bool``, the inputs checked once."""
    if not sensors:
        return np.zeros(0, dtype=bool)
    poses, mask = check_poses(poses, marker_mask)
    box = np.array([s.cull_box() for s in sensors])
    xy = poses[mask, :2]
    inside = (xy[None, :, 0] >= box[:, None, 0]) & (xy[None, :, 0] <= box[:, None, 2]) \
        & (xy[None, :, 1] >= box[:, None, 1]) & (xy[None, :, 1] <= box[:, None, 3])
    return inside.any(axis=1)


def check_poses(poses, marker_mask) -> tuple[np.ndarray, np.ndarray]:
    """Robot poses ``(N, 3)`` float and who carries markers ``(N,)`` bool (None: every robot), checked:
    ``ValueError`` naming the wrong shape or the non-finite poses."""
    poses = np.asarray(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3) (x, y, theta), got {poses.shape}")
    if not np.all(np.isfinite(poses)):
        raise ValueError("poses contain NaN or inf")
    mask = np.ones(len(poses), dtype=bool) if marker_mask is None else np.asarray(marker_mask, dtype=bool)
    if mask.shape != (len(poses),):
        raise ValueError(f"marker_mask must have shape ({len(poses)},), got {mask.shape}")
    return poses, mask


def _kernels():
    """The compiled per-pixel loops (numba is imported on first use, not with the package)."""
    from parcover_env.sensors import kinect_kernels

    return kinect_kernels


def _as_f32_bound(x) -> np.floating:
    """A range limit in the precision numpy compares it with a float32 image: a Python number is
    rounded to float32 (a weak scalar), a numpy float64 is kept (the image is promoted instead)."""
    return np.result_type(np.float32, x).type(x)
