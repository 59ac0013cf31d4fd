"""Follower's onboard camera: range, bearing and relative heading of the robot ahead.

The follower sees its predecessor (Min et al.: "followers simply follow the leader by using only their
camera sensor") if it lies within the camera's field of view and range and no wall blocks the line
of sight. No Kinect and no messages are involved.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from parcover_env.geometry import sight_lines_blocked
from parcover_env.geometry.records import record
from parcover_env.sensors import onboard_kernels
from parcover_env.sensors.base import SensingState

__all__ = ["RelativeCamera", "RelativeReading", "lines_of_sight_blocked"]


class RelativeReading(NamedTuple):
    """Per follower: predecessor position in the follower frame (m), relative heading (rad), seen
    (a read-only record, made for every world every step, hence a NamedTuple)."""

    rel_xy: np.ndarray
    rel_heading: np.ndarray
    visible: np.ndarray


@dataclass(frozen=True)
class RelativeCamera:
    """The follower's camera; the env builds it from ``FormationConfig.camera_*`` (units there)."""

    fov_deg: float = 120.0
    max_range: float = 2.5
    range_noise: float = 0.01
    """Range sigma (m) per metre of distance (stereo/marker cameras degrade with distance)."""
    bearing_noise: float = 0.01
    """Bearing sigma (rad)."""
    heading_noise: float = 0.03
    """Relative-heading sigma (rad)."""

    def measure(self, poses: np.ndarray, predecessor: np.ndarray, segments: np.ndarray,
                rng: np.random.Generator) -> RelativeReading:
        """``poses (N, 3)`` true poses; ``predecessor (N,)`` index of the robot each one follows, -1 none.
        The one-world call of :meth:`measure_many`."""
        r = self.measure_many(np.asarray(poses, dtype=float)[None], np.asarray(predecessor)[None], segments, [rng])
        return RelativeReading(r.rel_xy[0], r.rel_heading[0], r.visible[0])

    def measure_many(self, poses: np.ndarray, predecessor: np.ndarray, segments: np.ndarray,
                     rngs: Sequence[np.random.Generator]) -> RelativeReading:
        """:meth:`measure` of ``K`` worlds sharing the walls ``segments``: true poses ``(K, N, 3)``,
        ``predecessor (K, N)`` (within each world); a reading of ``(K, N, ...)`` arrays. Each world
        draws its followers' normals from its own generator (``rngs[k]``, as alone), then one line
        of sight test and one compiled pass cover every robot of every world (the worlds side by
        side on one robot axis; the predecessor indices moved with them), so world ``k`` reads
        bit for bit what it reads alone."""
        poses = np.asarray(poses, dtype=float)
        k, n = poses.shape[:2]
        target = _flat_targets(predecessor)
        px, py, pth = (np.ascontiguousarray(poses[..., c].ravel()) for c in range(3))
        blocked = sight_lines_blocked(px, py, target, np.ascontiguousarray(segments, dtype=float).reshape(-1, 4))
        follows = target >= 0
        followers = [int(np.count_nonzero(follows))] if k == 1 else follows.reshape(k, n).sum(axis=1).tolist()
        # range, bearing, heading; a world without followers draws nothing (its generator is left as is)
        if k > 1 and min(followers) == max(followers) > 0:  # as many in every world: one block, rows drawn into
            block = np.empty((k, 3, followers[0]))
            for rng, row in zip(rngs, block, strict=True):
                rng.standard_normal(out=row)
            z = block.transpose(1, 0, 2).reshape(3, -1)  # world after world along the followers' axis
        else:
            parts = [rng.standard_normal((3, f)) if f else _NO_DRAWS for rng, f in zip(rngs, followers, strict=True)]
            z = parts[0] if k == 1 else np.concatenate(parts, axis=1)
        rel_xy, rel_heading, visible = np.empty((k * n, 2)), np.empty(k * n), np.empty(k * n, dtype=bool)
        onboard_kernels.camera_view(px, py, pth, target, blocked, z, self.record, rel_xy, rel_heading, visible)
        return RelativeReading(rel_xy.reshape(k, n, 2), rel_heading.reshape(k, n), visible.reshape(k, n))

    @functools.cached_property
    def record(self) -> np.ndarray:
        """The camera's reach and noise as the compiled camera reads them
        (:data:`~parcover_env.sensors.onboard_kernels.CAMERA`; SI units, half the FOV)."""
        return record(onboard_kernels.CAMERA, max_range=self.max_range, half_fov=math.radians(self.fov_deg) / 2,
                      range_noise=self.range_noise, bearing_noise=self.bearing_noise,
                      heading_noise=self.heading_noise)

    size = 4
    """Numbers per robot of :meth:`sense`: the predecessor's x, y in this robot's frame (m), its
    relative heading (rad), seen (1) or not (0)."""

    def sense(self, state: SensingState, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """The :class:`~parcover_env.sensors.base.Sensor` reading ``(K, N, 4)`` (see :attr:`size`) of
        :meth:`measure_many`."""
        r = self.measure_many(state.poses, state.predecessor, state.segments, rngs)
        return np.concatenate([r.rel_xy, r.rel_heading[..., None], r.visible[..., None]], axis=2)

    @staticmethod
    def reading(row: np.ndarray) -> RelativeReading:
        """One world's :meth:`sense` rows ``(N, 4)`` as a :class:`RelativeReading`."""
        return RelativeReading(row[:, :2], row[:, 2], row[:, 3] > 0.5)


def lines_of_sight_blocked(poses: np.ndarray, predecessor: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """``(K, N)``: whether a wall cuts the line from each robot to its predecessor, for ``K`` worlds
    sharing the walls (``poses (K, N, 3)``, ``predecessor (K, N)`` indices within the world, -1 none:
    False) in one call; what :meth:`RelativeCamera.measure_many` tests."""
    poses = np.asarray(poses, dtype=float)
    px, py = (np.ascontiguousarray(poses[..., c].ravel()) for c in range(2))
    walls = np.ascontiguousarray(segments, dtype=float).reshape(-1, 4)
    return sight_lines_blocked(px, py, _flat_targets(predecessor), walls).reshape(poses.shape[:2])


_NO_DRAWS = np.empty((3, 0))
"""The normals of a world without followers (shared, never written)."""


def _flat_targets(predecessor: np.ndarray) -> np.ndarray:
    """``(K N,)`` int64: the predecessors ``(K, N)`` (within each world, -1 none) as indices into the
    worlds' robots side by side (world ``k``'s robots at ``k N ... (k + 1) N - 1``)."""
    predecessor = np.asarray(predecessor, dtype=np.int64)
    k, n = predecessor.shape
    if k == 1:
        return np.ascontiguousarray(predecessor[0])
    return np.where(predecessor >= 0, predecessor + n * np.arange(k)[:, None], -1).ravel()
