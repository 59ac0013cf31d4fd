"""Identity tracking across overhead Kinects: fuse overlapping views, match to predicted poses."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from parcover_env.localization.kinect.pipeline import PoseEstimate

__all__ = ["KinectTracker"]


class KinectTracker:
    """Fuses the estimates of several Kinects and keeps robot identities across frames.

    ``update`` merges estimates closer than ``fuse_radius`` (the same robot seen by overlapping
    Kinects; weighted by marker count, circular mean of headings), then assigns them to reference
    poses (``predicted`` by the caller, e.g. odometry, else the last tracked poses) by minimum-cost
    matching within ``gate`` metres. Without ``predicted``, unmatched estimates open new tracks.
    """

    def __init__(self, gate: float = 0.3, fuse_radius: float = 0.12):
        if not gate > 0 or not fuse_radius > 0:
            raise ValueError(f"gate and fuse_radius must be > 0, got {gate}, {fuse_radius}")
        self.gate = float(gate)
        self.fuse_radius = float(fuse_radius)
        self.poses: dict[int, np.ndarray] = {}
        self.last_seen: dict[int, float] = {}
        self.unassigned: list[np.ndarray] = []
        self._next_id = 0

    def fuse(self, estimates: Sequence[PoseEstimate]) -> list[np.ndarray]:
        """Merge estimates of the same robot from several Kinects: list of poses ``(3,)``."""
        clusters: list[list[PoseEstimate]] = []
        for e in sorted(estimates, key=lambda e: -e.n_markers):
            for cl in clusters:
                if math.hypot(cl[0].x - e.x, cl[0].y - e.y) <= self.fuse_radius:
                    cl.append(e)
                    break
            else:
                clusters.append([e])
        fused = []
        for cl in clusters:
            if len(cl) == 1:  # the formulas below for one estimate, in floats (the same operations)
                e, w1 = cl[0], float(cl[0].n_markers)
                ang = math.atan2(w1 * math.sin(e.theta), w1 * math.cos(e.theta))
                fused.append(np.array([(w1 * e.x) / w1, (w1 * e.y) / w1, ang]))
                continue
            w = np.array([e.n_markers for e in cl], dtype=float)
            xy = np.array([[e.x, e.y] for e in cl])
            th = np.array([e.theta for e in cl])
            ang = math.atan2(float(w @ np.sin(th)), float(w @ np.cos(th)))
            fused.append(np.array([*(w @ xy / w.sum()), ang]))
        return fused

    def update(self, estimates_per_kinect: Sequence[Sequence[PoseEstimate]],
               predicted: Mapping[int, Sequence[float]] | None = None,
               stamp: float = 0.0) -> dict[int, np.ndarray]:
        """Poses ``(x, y, theta)`` of the robots seen in this update, keyed by robot id."""
        fused = self.fuse([e for ests in estimates_per_kinect for e in ests])
        ref = {int(k): np.asarray(v, dtype=float) for k, v in (predicted if predicted is not None
                                                                 else self.poses).items()}
        ids = list(ref)
        out: dict[int, np.ndarray] = {}
        used = set()
        if len(fused) == 1 and len(ids) == 1:  # one candidate each (one leader): no assignment to solve
            if np.hypot(*(fused[0][:2] - ref[ids[0]][:2])) <= self.gate:
                out[ids[0]] = fused[0]
                used.add(0)
        elif fused and ids:
            f, p = np.array(fused), np.array([ref[k] for k in ids])
            cost = np.hypot(f[:, None, 0] - p[None, :, 0], f[:, None, 1] - p[None, :, 1])
            inside = cost <= self.gate
            if inside.sum(axis=0).max() <= 1 and inside.sum(axis=1).max() <= 1:
                # no estimate within the gate of two robots, nor a robot of two: the optimal assignment
                # holds every pair within the gate (any other pays 1e6), in ascending row order
                rows, cols = np.nonzero(inside)
            else:
                rows, cols = linear_sum_assignment(np.where(inside, cost, 1e6))
            for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
                if inside[r, c]:
                    out[ids[c]] = fused[r]
                    used.add(r)
        self.unassigned = [f for r, f in enumerate(fused) if r not in used]
        if predicted is None:
            for f in self.unassigned:
                while self._next_id in self.poses:
                    self._next_id += 1
                out[self._next_id] = f
                self._next_id += 1
            self.unassigned = []
        for k, v in out.items():
            self.poses[k] = v
            self.last_seen[k] = stamp
        return out

    def assign(self, fused: Sequence[np.ndarray], robots: Sequence[int], stamp: float = 0.0) -> dict[int, np.ndarray]:
        """Record an update whose fusion and matching were done elsewhere (the compiled common case,
        :func:`~parcover_env.localization.kinect.track_kernel.match`): ``fused`` poses ``(3,)`` in the
        tracker's order and the robot each was matched to (``robots``, -1: none). Returns the fixes
        ``{robot: pose}`` (in that order), as :meth:`update` with those matches."""
        out: dict[int, np.ndarray] = {}
        unassigned = []
        poses, last_seen = self.poses, self.last_seen
        for f, r in zip(fused, robots, strict=True):
            if r >= 0:
                out[r] = poses[r] = f
                last_seen[r] = stamp
            else:
                unassigned.append(f)
        self.unassigned = unassigned
        return out

    def age(self, robot_id: int, stamp: float) -> float:
        """Time since ``robot_id`` was last seen (inf if never): > the Kinect period means stale."""
        return stamp - self.last_seen[robot_id] if robot_id in self.last_seen else math.inf
