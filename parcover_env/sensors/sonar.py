"""Sonar ring model (Kim, Pearce & Amato): ranges per beam for all robots in one vectorized numpy pass.

Geometry and conventions
- The transducers sit at the robot centre (a documented simplification: ranges are measured from
  the centre, so a wall touching the robot reads ``robot_radius``). Beam angles are in the robot
  frame, counter-clockwise from the heading. All rays are cast with the formulas of
  :mod:`parcover_env.geometry.rays` (its compiled per-ray helpers, in :mod:`.sonar_kernels` and
  :mod:`.sonar_ring_kernels`).
- ``model: ray`` — one ideal ray along each beam axis; reading = first hit (walls or other robots).
- ``model: fast`` — the ``ray`` model's noise-free reading, then dropouts (an echo lost at
  ``dropout_prob``) and the noise below; no cone, no specular incidence limit, no multipath, no
  corners, no cross-talk (:mod:`.sonar_fast_kernels`). The cheap option for training.
- ``model: specular`` (default) — each beam is a cone of ``cone_deg`` sampled by ``n_subrays`` rays (the
  axis direction rotated by each sub-ray's offset). Overlapping cones share the sub-rays that point
  the same way (within 1e-9 rad): the default ring of 16 beams traces 48 rays, not 80.
  A sub-ray echoes from a wall only when it meets the wall within ``incidence_max_deg`` of the
  normal; otherwise it is mirrored away and, with ``multipath``, followed to the next surface: if
  that one returns it (normal enough, or a robot) the echo retraces the path and reads the
  two-bounce length ``t1 + t2`` (too long), else it is lost. Other robots (cylinders) always echo;
  a concave corner (two walls meeting at < 180 deg, seen from inside their wedge) inside the cone
  and in line of sight retro-reflects at the corner distance. The reading is the nearest echo in
  the cone.
- Cross-talk (:func:`crosstalk`, only in :meth:`SonarRing.measure` with an rng): with probability
  ``crosstalk_prob`` a beam facing another robot whose ring fires back at it reads half their
  distance (the other ping's one-way time of flight, halved as a round trip).
- No echo, or an echo beyond ``range_max``, reads ``range_max`` ("too far", the paper's 2.54 m); an
  echo nearer than ``range_min`` is lost (``below_min: drop``) or clipped (``clip``).
  Echoes get noise ``N(0, (noise_std + noise_rel * r)^2)``, are quantized to ``quantization`` and
  clamped to ``[range_min, range_max]``. ``garbage_rate`` replaces readings by uniform random ranges.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from parcover_env.config import SonarConfig
from parcover_env.geometry import rays
from parcover_env.geometry.angles import wrap_angle
from parcover_env.geometry.records import record
from parcover_env.geometry.wall_grid import WallGrid, build_wall_grid
from parcover_env.sensors import sonar_fast_kernels as fast_kern
from parcover_env.sensors import sonar_kernels as kern
from parcover_env.sensors import sonar_ring_kernels as ring_kern
from parcover_env.sensors.base import SensingState

__all__ = ["SonarRing", "AMIGOBOT_ANGLES_DEG", "concave_corners", "simulate_beams", "beam_kernel_arguments",
           "crosstalk"]

AMIGOBOT_ANGLES_DEG = (90.0, 44.0, 12.0, -12.0, -44.0, -90.0, -144.0, 144.0)
"""AmigoBot sonar layout (robot frame, deg): six forward-facing transducers and two rear ones."""

_NUDGE = 1e-7
"""A reflected ray starts this far off the wall it left, so that it does not hit that wall again (m)."""


@dataclass(frozen=True, eq=False)
class _Walls:
    """What the sonar kernels need of a wall set, derived once per set (read-only arrays)."""

    kernel: kern.WallSet
    """Segments ``(S, 4)`` C-contiguous, their lengths (m), the corners and their wall directions."""
    grids: dict[float, WallGrid] = field(default_factory=dict, repr=False)
    """The :class:`~parcover_env.geometry.wall_grid.WallGrid` of each reach asked for (:meth:`grid`)."""

    def grid(self, reach: float) -> WallGrid:
        """The walls' grid for near-wall lists of ``reach`` (m), built once (an infinite reach: a grid
        whose every lookup tests every wall)."""
        found = self.grids.get(reach)
        if found is None:
            found = self.grids[reach] = build_wall_grid(self.segments, reach if math.isfinite(reach) else 0.0)
        return found

    @property
    def segments(self) -> np.ndarray:
        return self.kernel.segments

    @property
    def corners(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Corner vertices and their wall directions (:func:`concave_corners`)."""
        return self.kernel.points, self.kernel.u1, self.kernel.u2


@lru_cache(maxsize=32)
def _walls_of(seg_bytes: bytes, n: int) -> _Walls:
    return _Walls(kern.wall_set(np.frombuffer(seg_bytes, dtype=float).reshape(n, 4)))


def _walls(segments: np.ndarray) -> _Walls:
    if _frozen(segments) and segments is _last_walls[0]:
        return _last_walls[1]
    seg = np.ascontiguousarray(np.asarray(segments, dtype=float).reshape(-1, 4))
    walls = _walls_of(seg.tobytes(), len(seg))
    if _frozen(segments):
        _last_walls[:] = [segments, walls]
    return walls


_last_walls: list = [None, None]
"""The last frozen wall array :func:`_walls` saw and its ``_Walls`` (a map's walls, every step)."""


def _frozen(a) -> bool:
    """A read-only float64 ``(S, 4)`` C-contiguous array that owns its data (e.g. ``MapModel.segments``):
    its contents cannot change, so what is derived from it is kept by identity, unchecked."""
    return (type(a) is np.ndarray and a.base is None and not a.flags.writeable and a.dtype == np.float64
            and a.ndim == 2 and a.shape[1] == 4 and a.flags.c_contiguous)


def concave_corners(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices shared by exactly two non-collinear segments: ``(points (C,2), u1 (C,2), u2 (C,2))``
    with ``u1, u2`` the unit wall directions leaving the vertex. Whether a vertex is concave depends
    on the viewpoint: an echo needs the sensor strictly inside the < 180 deg wedge the two walls
    span (:func:`simulate_beams`). Cached per segment array contents (read-only arrays)."""
    return _walls(segments).corners


@lru_cache(maxsize=32)
def _subray_offsets(cone_deg: float, n_subrays: int) -> np.ndarray:
    """Angles (rad) of a cone's sub-rays about its axis: ``n_subrays`` spread evenly over the cone."""
    offsets = np.linspace(-0.5, 0.5, n_subrays) * math.radians(cone_deg)
    offsets.setflags(write=False)
    return offsets


_SAME_RAY = 1e-9
"""Sub-rays of overlapping cones pointing within this (rad) of each other are one ray, traced once."""


@lru_cache(maxsize=64)
def _shared_subrays(rel_bytes: bytes, offsets_bytes: bytes) -> np.ndarray:
    """``share (B, J)``: for beam ``b`` (axis ``rel[b]`` off the first beam's, rad, float64 bytes) and
    sub-ray offset ``j``, the flat index ``b' * J + j'`` of the first pair in that order whose
    direction is within :data:`_SAME_RAY` of it (its own index if none comes before)."""
    rel, offsets = np.frombuffer(rel_bytes, dtype=float), np.frombuffer(offsets_bytes, dtype=float)
    ang = (rel[:, None] + offsets[None, :]).ravel()
    same = np.abs(wrap_angle(ang[:, None] - ang[None, :])) < _SAME_RAY
    share = np.argmax(same, axis=1)  # the first match (each pair matches itself)
    while not np.array_equal(share[share], share):  # chains of near matches: all to their first
        share = share[share]
    share = np.ascontiguousarray(share.reshape(len(rel), len(offsets)), dtype=np.int64)
    share.setflags(write=False)
    return share


def _share(axes: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """:func:`_shared_subrays` of beams ``axes (N, B)`` whose rows all have the first row's pattern
    (a ring on robots of any heading: the axis pattern rounded to 1e-9 rad); no sharing otherwise."""
    if axes.size == 0:
        return np.zeros((axes.shape[1], len(offsets)), dtype=np.int64)
    rel = axes[0] - axes[0, 0]
    if len(axes) > 1 and not _same_pattern((axes - axes[:, :1]) - rel):
        return np.arange(axes.shape[1] * len(offsets), dtype=np.int64).reshape(axes.shape[1], len(offsets))
    return _shared_subrays(np.round(rel, 9).tobytes(), offsets.tobytes())


def _same_pattern(gap: np.ndarray) -> bool:
    """Whether every angle ``gap`` (rad) is within :data:`_SAME_RAY` of a whole turn (most often of 0)."""
    return bool(np.abs(gap).max() < _SAME_RAY or np.all(np.abs(wrap_angle(gap)) < _SAME_RAY))


def simulate_beams(cfg: SonarConfig, origins: np.ndarray, axes: np.ndarray, segments: np.ndarray,
                   centres: np.ndarray, radius: float, owner: np.ndarray, n_subrays: int = 5) -> np.ndarray:
    """Noise-free readings ``(N, B)`` for beams with world axis angles ``axes (N, B)`` from
    ``origins (N, 2)``; discs ``centres (D, 2)`` (or ``(N, D, 2)``, a disc set per origin: batched
    worlds) of ``radius`` block and echo (``owner (N,)`` = own disc index or -1). Values beyond
    ``range_max`` (no echo) read ``range_max``."""
    n, b = axes.shape
    rmax = float(cfg.range_max)
    walls = _walls(segments)
    offsets = _offsets(cfg, n_subrays)
    rules = _rules(cfg, box_cull=rays.BOX_CULL)
    # one compiled pass over all sub-rays of all robots: walls, discs, incidence, second bounces
    origins = np.asarray(origins, dtype=float).reshape(-1, 2)
    ox, oy = np.ascontiguousarray(origins[:, 0]), np.ascontiguousarray(origins[:, 1])
    axes = np.ascontiguousarray(axes, dtype=float)
    discs = kern.Discs(*rays.disc_planes(centres, float(radius), owner, n))
    reading = np.empty((n, b))
    kern.beam_readings(ox, oy, axes, offsets, _share(axes, offsets), walls.kernel, discs, rules, reading)
    return np.minimum(reading, rmax, out=reading)


def beam_kernel_arguments(cfg: SonarConfig, segments: np.ndarray, axes: np.ndarray,
                          n_subrays: int = 5) -> tuple:
    """What :func:`simulate_beams` hands :func:`~parcover_env.sensors.sonar_kernels.beam_readings` for
    beams ``axes (N, B)`` on the walls ``segments``: ``(walls, offsets, share, rules)`` (the
    :class:`~parcover_env.sensors.sonar_kernels.WallSet`, the sub-ray offsets, the shared sub-rays and the
    :data:`~parcover_env.sensors.sonar_kernels.SONAR_RULES` record), for compiled code that casts beams of
    that pattern many times (the sonar localizer's polish) with the same float operations. Readings
    are then ``min(reading, range_max)`` as here."""
    offsets = _offsets(cfg, n_subrays)
    share = _share(np.ascontiguousarray(axes, dtype=float), offsets)
    return _walls(segments).kernel, offsets, share, _rules(cfg, box_cull=rays.BOX_CULL)


_NONE = np.empty(0)  # an empty draw (that step is off); never written
_DRAW_INTO = {"random": np.random.Generator.random, "normal": np.random.Generator.standard_normal}
"""The draws of :meth:`SonarRing._fill` by kind (``uniform``: :meth:`SonarRing._uniform`), written ``out=``."""
_AXIS_ONLY = np.zeros(1)
"""Sub-ray offsets of the ``ray`` model: the beam axis alone."""


def _offsets(cfg: SonarConfig, n_subrays: int) -> np.ndarray:
    """A beam's sub-ray offsets (rad): the cone's, or the axis alone (``model: ray``)."""
    return _subray_offsets(float(cfg.cone_deg), n_subrays) if cfg.model == "specular" else _AXIS_ONLY


@lru_cache(maxsize=32)
def _rules(cfg: SonarConfig, box_cull: bool = True, all_round: bool = False) -> np.ndarray:
    """The :data:`~parcover_env.sensors.sonar_kernels.SONAR_RULES` record of a sonar (cached: the
    config is frozen)."""
    return record(kern.SONAR_RULES, range_max=cfg.range_max, specular=cfg.model == "specular",
                  multipath=cfg.multipath, cos_min=_cos_min(cfg), nudge=_NUDGE, box_cull=box_cull,
                  half_cone=_half_cone(cfg), all_round=all_round, near_slack=rays.NEAR_SLACK,
                  crosstalk_prob=cfg.crosstalk_prob, range_min=cfg.range_min, drop_below=cfg.below_min == "drop",
                  noise_std=cfg.noise_std, noise_rel=cfg.noise_rel, quantization=cfg.quantization,
                  garbage_rate=cfg.garbage_rate, dropout_prob=cfg.dropout_prob if cfg.model == "fast" else 0.0)


def _cos_min(cfg: SonarConfig) -> float:
    """The smallest ``|cos|`` of incidence at which a wall echoes, with a rounding slack."""
    return math.cos(math.radians(cfg.incidence_max_deg)) - 1e-12


def _half_cone(cfg: SonarConfig) -> float:
    """Half the beam's cone (rad), with a rounding slack: a bearing this far off the axis is inside."""
    return math.radians(cfg.cone_deg) / 2 + 1e-12


class SonarRing:
    """A ring of sonar transducers (``cfg.layout``) plus the rotating 360-degree scan mode."""

    def __init__(self, cfg: SonarConfig, n_subrays: int = 5):
        if not isinstance(cfg, SonarConfig):
            raise ValueError(f"SonarRing needs a SonarConfig, got {type(cfg).__name__}")
        if n_subrays < 1:
            raise ValueError(f"n_subrays must be >= 1, got {n_subrays}")
        self.cfg = cfg
        self.n_subrays = int(n_subrays)
        if cfg.layout == "amigobot":
            self.beam_angles = np.radians(np.array(AMIGOBOT_ANGLES_DEG))
        else:
            self.beam_angles = np.arange(cfg.n_beams) * (2 * math.pi / cfg.n_beams)
        n_scan = round(360.0 / cfg.scan_step_deg)
        self.scan_angles = np.radians(np.arange(n_scan) * cfg.scan_step_deg)
        """Robot-frame angles of the 360-degree scan (72 readings at 5 deg)."""
        self._checked: np.ndarray | None = None  # the last wall array measure() checked, if frozen (_frozen)
        self._reach = float(cfg.range_max) + rays.NEAR_SLACK
        """The reach of the rings' near-wall lists (m)."""
        self._beams = np.ascontiguousarray(self.beam_angles, dtype=float)
        self._offsets = _offsets(cfg, self.n_subrays)
        self._share = _share(self._beams[None], self._offsets)
        """The ring's shared sub-rays (:func:`_share`)."""
        self._rules = _rules(cfg, all_round=_covers_circle(self._beams.tobytes(), _half_cone(cfg)))
        """The constants of the compiled ring (:data:`~parcover_env.sensors.sonar_kernels.SONAR_RULES`)."""

    @property
    def n_beams(self) -> int:
        return len(self.beam_angles)

    def measure(self, poses, segments, robot_radius: float, rng: np.random.Generator | None,
                include_robots: bool = True) -> np.ndarray:
        """Ring readings ``(N, B)`` float32 for all robots ``poses (N, 3)`` at once. Other robots are
        discs of ``robot_radius`` that block and echo, and whose rings may cross-talk
        (``include_robots``). ``rng=None``: noise-free and no cross-talk. With a generator and other
        robots, one compiled call (:meth:`draw`, then :meth:`readings`); the same numbers as its
        parts (:func:`simulate_beams`, :func:`crosstalk`, :meth:`corrupt`'s noise)."""
        poses = _as_array(poses, "poses", (-1, 3))
        if segments is not self._checked:  # a frozen wall array is checked once
            segments = _as_array(segments, "segments", (-1, 4))
            self._checked = segments if _frozen(segments) else None
        n = len(poses)
        if include_robots and rng is not None:
            return self.readings(poses[None], segments, robot_radius, [self.draw(n, rng)])[0]
        axes = poses[:, 2:3] + self.beam_angles[None, :]
        centres = poses[:, :2] if include_robots else np.zeros((0, 2))
        owner = np.arange(n) if include_robots else np.full(n, -1)
        ideal = simulate_beams(self.cfg, poses[:, :2], axes, segments, centres, robot_radius, owner, self.n_subrays)
        return self._noisy(ideal, None, rng, np.float32)

    @property
    def size(self) -> int:
        """Readings per robot (:class:`~parcover_env.sensors.base.Sensor`): one per beam."""
        return self.n_beams

    def sense(self, state: SensingState, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """The :class:`~parcover_env.sensors.base.Sensor` reading ``(K, N, B)`` float32: each world's :meth:`draw`
        (written into one block per kind, row ``k`` world ``k``'s), then one :meth:`readings` of all."""
        n, size = state.n_robots, state.n_robots * self.n_beams
        kinds = self._kinds(n > 1)
        blocks = [np.empty((len(rngs), size)) if kind else _NONE for kind in kinds]
        plan = [(_DRAW_INTO.get(kind, self._uniform), b) for kind, b in zip(kinds, blocks, strict=True) if kind]
        for k, rng in enumerate(rngs):  # world k's draws, kind after kind (:meth:`_fill`'s order)
            for draw, b in plan:
                draw(rng, out=b[k])
        return self.readings(state.poses, state.segments, state.robot_radius, [[b.reshape(-1) for b in blocks]])

    def draw(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
        """The random numbers :meth:`measure` draws for ``n`` robots that see each other, in its order:
        cross-talk uniforms, noise normals, garbage uniforms and ranges (each ``(n * B,)``, empty
        where that step is off); for :meth:`readings`. ``model: fast``: noise normals, dropout
        uniforms, garbage uniforms and ranges (:class:`~.sonar_fast_kernels.FastDraws`)."""
        return self._draws(n * self.n_beams, rng, n > 1)

    def _kinds(self, talk: bool) -> tuple[str | None, ...]:
        """What :meth:`draw`'s four arrays hold (``random``, ``normal``, ``uniform``, None: off)."""
        cfg = self.cfg
        noise = "normal" if cfg.noise_std > 0 or cfg.noise_rel > 0 else None
        bad = "random" if cfg.garbage_rate > 0 else None
        junk = "uniform" if bad else None
        if cfg.model == "fast":
            return noise, "random" if cfg.dropout_prob > 0 else None, bad, junk
        return "random" if talk and cfg.crosstalk_prob > 0 else None, noise, bad, junk

    def _fill(self, kinds: tuple[str | None, ...], rng: np.random.Generator, outs: list[np.ndarray]) -> None:
        """Draw ``outs`` from ``rng`` as ``kinds`` says, in order (``out=``: a fresh array's numbers)."""
        for kind, out in zip(kinds, outs, strict=True):
            if kind:
                _DRAW_INTO.get(kind, self._uniform)(rng, out=out)

    def _uniform(self, rng: np.random.Generator, out: np.ndarray) -> None:
        """``out`` uniform in ``[range_min, range_max]`` (the garbage readings; a fresh array's numbers)."""
        out[:] = rng.uniform(self.cfg.range_min, self.cfg.range_max, len(out))

    def _draws(self, size: int, rng: np.random.Generator | None, talk: bool) -> tuple[np.ndarray, ...]:
        """``size`` of each of :meth:`draw`'s numbers (cross-talk only if ``talk``; none without ``rng``)."""
        kinds = self._kinds(talk) if rng is not None else (None,) * 4
        outs = [np.empty(size) if kind else _NONE for kind in kinds]
        self._fill(kinds, rng, outs)
        return fast_kern.FastDraws(*outs) if self.cfg.model == "fast" else tuple(outs)

    def readings(self, poses: np.ndarray, segments: np.ndarray, robot_radius: float,
                 draws: list[tuple[np.ndarray, ...]]) -> np.ndarray:
        """Readings ``(K, N, B)`` float32 of ``K`` worlds sharing the walls ``segments``, robots ``poses
        (K, N, 3)`` that see the robots of their own world, with each world's :meth:`draw`: one
        compiled call (:func:`~parcover_env.sensors.sonar_ring_kernels.ring_readings`; one entry in
        ``draws``: every world's draws joined, world after world). World ``k`` reads what
        :meth:`measure` reads for it alone with a generator that gives those draws."""
        flat = [np.concatenate(parts) for parts in zip(*draws, strict=True)] if len(draws) > 1 else draws[0]
        walls = _walls(segments)
        poses = np.ascontiguousarray(poses, dtype=float)
        k, n, nb = poses.shape[0], poses.shape[1], self.n_beams
        out = np.empty((k * n, nb), dtype=np.float32)
        r = float(robot_radius)
        if self.cfg.model == "fast":
            fast_kern.fast_ring_readings(poses, r * r, self._beams, walls.segments, self._grid(walls),
                                         fast_kern.FastDraws(*flat), self._rules, out)
        else:
            ring_kern.ring_readings(poses, r * r, self._beams, self._offsets, self._share, walls.kernel,
                                    self._grid(walls), ring_kern.Draws(*flat), self._rules, out)
        return out.reshape(k, n, nb)

    def _grid(self, walls: _Walls) -> WallGrid:
        """The grid of ``walls`` for this ring's near-wall lists (``range_max`` plus the slack; kept
        with the walls, shared by every ring and world)."""
        return walls.grid(self._reach)

    def ideal_batch(self, poses: np.ndarray, segments: np.ndarray, robot_radius: float) -> np.ndarray:
        """Noise-free readings ``(K, N, B)`` of ``K`` worlds sharing the walls ``segments``, robots
        ``poses (K, N, 3)``, in one cast: each robot's beams see the walls and the other robots of
        its own world. Row ``k`` equals the noise-free readings :meth:`measure` computes for world
        ``k`` alone (``rng=None``; bit for bit)."""
        poses = np.asarray(poses, dtype=float)
        k, n = poses.shape[:2]
        flat = poses.reshape(k * n, 3)
        axes = flat[:, 2:3] + self.beam_angles[None, :]
        centres = np.broadcast_to(poses[:, None, :, :2], (k, n, n, 2)).reshape(k * n, n, 2)
        owner = np.tile(np.arange(n), k)
        ideal = simulate_beams(self.cfg, flat[:, :2], axes, np.asarray(segments, dtype=float), centres,
                               robot_radius, owner, self.n_subrays)
        return ideal.reshape(k, n, -1)

    def scan(self, pose, segments, other_robot_centres, robot_radius: float,
             rng: np.random.Generator | None) -> np.ndarray:
        """360-degree scan ``(len(scan_angles),)`` from ``pose (3,)`` (the paper's rotate-in-place
        mode: one beam every ``scan_step_deg``). ``rng=None`` gives the noise-free synthetic scan."""
        pose = _as_array(pose, "pose", (3,))
        segments = _as_array(segments, "segments", (-1, 4))
        others = np.zeros((0, 2)) if other_robot_centres is None else \
            _as_array(other_robot_centres, "other_robot_centres", (-1, 2))
        axes = (pose[2] + self.scan_angles)[None, :]
        ideal = simulate_beams(self.cfg, pose[None, :2], axes, segments, others, robot_radius,
                               np.array([-1]), self.n_subrays)[0]
        return self.corrupt(ideal, rng)

    def corrupt(self, ideal: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        """Dropouts below ``range_min``, noise, quantization, clamping and garbage readings applied
        to noise-free ranges (float64, shaped like ``ideal``)."""
        return self._noisy(ideal, None, rng, np.float64)

    def _noisy(self, ideal, heard: np.ndarray | None, rng: np.random.Generator | None, dtype) -> np.ndarray:
        """Readings from noise-free ranges: cross-talk with ``heard`` (if given, at ``crosstalk_prob``),
        then :meth:`corrupt`'s steps; one compiled pass drawing from ``rng``
        (:func:`~parcover_env.sensors.sonar_ring_kernels.ring_noise`)."""
        ideal = np.asarray(ideal, dtype=float)
        rows = np.ascontiguousarray(ideal.reshape(-1, ideal.shape[-1]) if ideal.ndim else ideal.reshape(1, 1))
        out = np.empty(rows.shape, dtype=dtype)
        talk = heard is not None
        if self.cfg.model == "fast":  # never cross-talk
            fast_kern.fast_noise(rows, self._draws(rows.size, rng, False), self._rules, out)
            return out.reshape(ideal.shape)
        heard = np.ascontiguousarray(heard, dtype=float).reshape(rows.shape) if talk else rows
        ring_kern.ring_noise(rows, heard, float(self.cfg.crosstalk_prob) if talk else 0.0,
                             ring_kern.Draws(*self._draws(rows.size, rng, talk)), self._rules, out)
        return out.reshape(ideal.shape)


def crosstalk(cfg: SonarConfig, poses: np.ndarray, beam_angles: np.ndarray, segments: np.ndarray,
              want: np.ndarray | None = None) -> np.ndarray:
    """``(N, B)`` reading each beam gets from another robot's ring (``inf`` if none): beam ``b`` of
    robot ``i`` hears beam ``c`` of robot ``j`` when each robot lies inside the other beam's cone and
    no wall is between them; the ping travels ``d`` one way, read as ``d / 2`` (range = c t / 2).
    The nearest such robot counts. Transducers sit at the robot centres (see the module notes).
    ``poses (K, N, 3)``: K worlds sharing the walls in one call (robots hear their own world only),
    ``(K, N, B)`` out, each world's rows equal to its own call bit for bit. ``want`` (bool, shaped
    like the output): compute only those beams, the others read inf (default: all)."""
    poses = np.asarray(poses, dtype=float)
    if poses.ndim == 2:
        return crosstalk(cfg, poses[None], beam_angles, segments, None if want is None else want[None])[0]
    k, n, nb = poses.shape[0], poses.shape[1], len(beam_angles)
    out = np.full((k, n, nb), np.inf)
    if n < 2:
        return out
    want = np.ones((k, n, nb), dtype=bool) if want is None else np.ascontiguousarray(want, dtype=bool)
    segments = _walls(segments).segments
    px, py, pth = (np.ascontiguousarray(poses[..., c]) for c in range(3))
    beams = np.ascontiguousarray(beam_angles, dtype=float)
    ring_kern.sonar_crosstalk(px, py, pth, beams, _covers_circle(beams.tobytes(), _half_cone(cfg)), segments,
                              _rules(cfg), want, out)
    return out


@lru_cache(maxsize=32)
def _covers_circle(beam_bytes: bytes, half: float) -> bool:
    """Whether cones of half-angle ``half`` about the beam axes (rad, float64 bytes) cover every
    direction, with a 1e-6 rad margin: the largest circular gap between neighbouring axes is below
    ``2 half``."""
    beams = np.frombuffer(beam_bytes, dtype=float)
    if len(beams) == 0:
        return False
    axes = np.sort(np.mod(beams, 2 * math.pi))
    gaps = np.diff(np.append(axes, axes[0] + 2 * math.pi))
    return bool(gaps.max() < 2 * half - 1e-6)


def _as_array(x, name: str, shape: tuple[int, ...]) -> np.ndarray:
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numeric, got {type(x).__name__}") from None
    if shape[0] == -1 and a.ndim == 1 and a.size == shape[1] and name != "segments":
        a = a[None, :]
    if shape[0] == -1 and a.size == 0:
        return a.reshape(0, shape[1])
    if a.ndim != len(shape) or any(s not in (-1, d) for s, d in zip(shape, a.shape, strict=True)):
        want = "(N, " + ", ".join(str(s) for s in shape[1:]) + ")" if shape[0] == -1 else str(shape)
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return a
