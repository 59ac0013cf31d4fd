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

import numpy as np

from parcover_env.geometry import sight_lines_blocked
from parcover_env.geometry.records import record
from parcover_env.sensors import onboard_kernels
from parcover_env.sensors.base import SensingState

__all__ = ["RelativeCamera", "RelativeReading", "lines_of_sight_blocked"]


@dataclass(frozen=True)
class RelativeReading:
    """Per follower: predecessor position in the follower frame (m), relative heading (rad), seen."""

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
                rng: np.random.Generator, blocked: np.ndarray | None = None) -> RelativeReading:
        """``poses (N, 3)`` true poses; ``predecessor (N,)`` index of the robot each one follows, -1 none.
        ``blocked (N,)``: whether a wall cuts each robot's line of sight to its predecessor, if
        already computed (:func:`lines_of_sight_blocked` over batched worlds)."""
        poses = np.asarray(poses, dtype=float)
        predecessor = np.ascontiguousarray(predecessor, dtype=np.int64)
        n = len(poses)
        px, py, pth = (np.ascontiguousarray(poses[:, c]) for c in range(3))
        if blocked is None:
            walls = np.ascontiguousarray(segments, dtype=float).reshape(-1, 4)
            blocked = sight_lines_blocked(px, py, predecessor, walls)
        rel_xy, rel_heading, visible = np.empty((n, 2)), np.empty(n), np.empty(n, dtype=bool)
        z = rng.standard_normal((3, int(np.count_nonzero(predecessor >= 0))))  # range, bearing, heading
        onboard_kernels.camera_view(px, py, pth, predecessor, np.ascontiguousarray(blocked, dtype=bool), z,
                                    self.record, rel_xy, rel_heading, visible)
        return RelativeReading(rel_xy, rel_heading, visible)

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
        """The :class:`~parcover_env.sensors.base.Sensor` reading ``(K, N, 4)`` (see :attr:`size`):
        every world's lines of sight in one test (one world: :meth:`measure` tests them), then
        :meth:`measure` of each world with its own generator."""
        k = state.n_worlds
        blocked = lines_of_sight_blocked(state.poses, state.predecessor, state.segments) if k > 1 else [None]
        out = np.empty((k, state.n_robots, self.size))
        for w, rng in enumerate(rngs):
            r = self.measure(state.poses[w], state.predecessor[w], state.segments, rng, blocked[w])
            np.concatenate([r.rel_xy, r.rel_heading[:, None], r.visible[:, None]], axis=1, out=out[w])
        return out

    @staticmethod
    def reading(row: np.ndarray) -> RelativeReading:
        """One world's :meth:`sense` rows ``(N, 4)`` as a :class:`RelativeReading`."""
        return RelativeReading(row[:, :2], row[:, 2], row[:, 3] > 0.5)


def lines_of_sight_blocked(poses: np.ndarray, predecessor: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """``(K, N)``: whether a wall cuts the line from each robot to its predecessor, for ``K`` worlds
    sharing the walls (``poses (K, N, 3)``, ``predecessor (K, N)`` indices within the world, -1 none:
    False) in one call; equal to what :meth:`RelativeCamera.measure` tests for each world alone."""
    poses = np.asarray(poses, dtype=float)
    predecessor = np.asarray(predecessor, dtype=np.int64)
    k, n = predecessor.shape
    target = np.where(predecessor >= 0, predecessor + n * np.arange(k)[:, None], -1).ravel()  # into the flat worlds
    px, py = (np.ascontiguousarray(poses[..., c].ravel()) for c in range(2))
    return sight_lines_blocked(px, py, target, np.ascontiguousarray(segments, dtype=float).reshape(-1, 4)).reshape(k, n)
