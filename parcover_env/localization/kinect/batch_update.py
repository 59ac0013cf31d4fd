"""The Kinect systems of ``K`` worlds in one step (:func:`update_systems`); one system is ``K = 1``.

Min, Fehr & Papanikolopoulos localize the group leaders with overhead Kinects. Per world this is
:meth:`KinectSystem.update <parcover_env.localization.kinect.system.KinectSystem.update>`: the
Kinects due at the world's clock, their estimates of the marker carriers, and the tracker's match
of those estimates to the carriers' predicted poses. Here the estimate model (``kinect: estimate``)
of every due Kinect of every world runs in ONE compiled call over the (world, Kinect, robot) axis
(:func:`~parcover_env.localization.kinect.estimate_kernel.candidates`: projection, visibility,
wall occlusion, detection probability, the reconstructed pose), and then each world draws its
random numbers from its own generator in the order the per-world model draws them (per due Kinect
a frame-drop uniform if its drop rate is positive, then per visible carrier a detection uniform
and, if detected, three normals), so world ``k`` gets the same floats as alone. ``kinect:
frames`` (rendering) stays per world (:meth:`KinectSystem.frame_estimates`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from parcover_env.geometry.wrap_formula import wrap
from parcover_env.localization.kinect import estimate_kernel
from parcover_env.localization.kinect.pipeline import PoseEstimate
from parcover_env.sensors.kinect import check_poses

if TYPE_CHECKING:
    from parcover_env.localization.kinect.system import KinectSystem

__all__ = ["update_systems", "fast_estimates"]


def update_systems(systems: Sequence[KinectSystem], times: Sequence[float], true: np.ndarray, markers: np.ndarray,
                   predicted: np.ndarray, rngs: Sequence[np.random.Generator]) -> list[dict[int, np.ndarray]]:
    """Pose fixes ``{robot index: (x, y, theta)}`` of each of ``K`` Kinect systems (one scenario)
    at its world's time ``times[k]``, true poses ``true[k] (N, 3)``, marker carriers
    ``markers[k] (N,)`` and predicted poses ``predicted[k] (N, 3)``, drawing from ``rngs[k]``."""
    out: list[dict[int, np.ndarray]] = [{} for _ in systems]
    batch: list[tuple[int, np.ndarray]] = []
    for k, s in enumerate(systems):
        time = times[k]
        due = np.flatnonzero(s.next_tick <= time + 1e-9)
        s.last_fixes = {}
        if len(due) == 0 or not markers[k].any():
            s.next_tick[due] = time + s.periods[due]
        elif s.fast is None:
            per_kinect = s.frame_estimates(due, true[k], markers[k], rngs[k], time)
            s.next_tick[due] = time + s.periods[due]
            out[k] = s.track(per_kinect, markers[k], predicted[k], time)
        else:
            check_poses(true[k], markers[k])
            batch.append((k, due))
    groups: dict[tuple, list[tuple[int, np.ndarray]]] = {}
    for item in batch:  # worlds sharing the static Kinect scenes (the batched worlds do) go together
        groups.setdefault(tuple(map(id, systems[item[0]].fast.depths)), []).append(item)
    for group in groups.values():
        ks = [k for k, _ in group]
        per = fast_estimates([systems[k] for k in ks], [due for _, due in group], true[ks], markers[ks],
                             [times[k] for k in ks], [rngs[k] for k in ks])
        for (k, due), per_kinect in zip(group, per, strict=True):
            s = systems[k]
            s.next_tick[due] = times[k] + s.periods[due]
            out[k] = s.track(per_kinect, markers[k], predicted[k], times[k])
    return out


def fast_estimates(systems: Sequence[KinectSystem], dues: Sequence[np.ndarray], true: np.ndarray,
                   markers: np.ndarray, times: Sequence[float], rngs: Sequence[np.random.Generator]
                   ) -> list[list[list[PoseEstimate]]]:
    """The estimate model of the Kinects ``dues[b]`` of each system ``b`` (their estimate models
    share one set of static depths) at true poses ``true[b] (N, 3)`` of the carriers ``markers[b]``:
    per system, one list of estimates per due Kinect (as
    :meth:`~parcover_env.localization.kinect.estimate_model.FastModel.estimate`)."""
    models = [s.fast for s in systems]
    n_kinects = len(models[0].sensors)
    rows = np.concatenate([b * n_kinects + due for b, due in enumerate(dues)]).astype(np.int64)
    row_world = np.repeat(np.arange(len(dues), dtype=np.int64), [len(due) for due in dues])
    row_depth = rows - row_world * n_kinects
    kinects = models[0].kinects if len(models) == 1 else np.concatenate([m.kinects for m in models])
    pattern = models[0].pattern if len(models) == 1 else np.concatenate([m.pattern for m in models])
    poses = np.ascontiguousarray(true, dtype=float)
    cap = len(rows) * poses.shape[1]
    out_row, out_index, out_geom = np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty((cap, 7))
    n = estimate_kernel.candidates(rows, row_world, row_depth, poses, np.ascontiguousarray(markers, dtype=bool),
                                   kinects, pattern, models[0].depths, models[0].noise, out_row, out_index, out_geom)
    n_markers = pattern.shape[1]
    drop = kinects["drop_rate"][rows].tolist()
    cand_row, cand_index, geom = out_row[:n].tolist(), out_index[:n].tolist(), out_geom[:n].tolist()
    per: list[list[list[PoseEstimate]]] = [[[] for _ in due] for due in dues]
    c = 0
    row_start = 0
    for b, due in enumerate(dues):
        rng, names, stamp = rngs[b], [s.name for s in models[b].sensors], times[b]
        for p in range(len(due)):
            r = row_start + p
            dropped = drop[r] > 0.0 and rng.random() < drop[r]
            found = per[b][p]
            while c < n and cand_row[c] == r:
                i = cand_index[c]
                p_det, merged, sigma_xy, sigma_th, x, y, th = geom[c]
                c += 1
                if dropped or merged or rng.random() >= p_det:
                    continue  # the frame dropped, the markers merged, or too small to be found
                z = rng.standard_normal(3).tolist()  # as rng.normal(0, sigma) three times
                found.append(PoseEstimate(x + (0.0 + sigma_xy * z[0]), y + (0.0 + sigma_xy * z[1]),
                                          wrap(th + (0.0 + sigma_th * z[2])), n_markers, kinect=names[due[p]],
                                          stamp=stamp, truth_index=i))
        row_start += len(due)
    return per
