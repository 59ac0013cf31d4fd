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
and, if detected, three normals), so world ``k`` gets the same floats as alone. The trackers of
all those worlds then fuse and match in ONE compiled call (:func:`track_all`,
:func:`~parcover_env.localization.kinect.track_kernel.match`); a world outside the common case
(estimates to fuse, a crowded gate) goes through its own tracker. ``kinect: frames`` (rendering)
stays per world (:meth:`KinectSystem.frame_estimates`).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from operator import is_
from typing import Any, NamedTuple

import numpy as np

from parcover_env.geometry.wrap_formula import wrap
from parcover_env.localization.kinect import batch_kernels, estimate_kernel, track_kernel
from parcover_env.localization.kinect.pipeline import PoseEstimate
from parcover_env.sensors.kinect import check_poses
from parcover_env.world.batching import stack

__all__ = ["update_systems", "fast_estimates", "track_all", "Detections"]


def update_systems(systems: Sequence[Any], times: Sequence[float], true: np.ndarray, markers: np.ndarray,
                   predicted: np.ndarray, rngs: Sequence[np.random.Generator],
                   ticks: np.ndarray | None = None) -> list[dict[int, np.ndarray]]:
    """Pose fixes ``{robot index: (x, y, theta)}`` of each of ``K`` Kinect systems (one scenario)
    at its world's time ``times[k]``, true poses ``true[k] (N, 3)``, marker carriers
    ``markers[k] (N,)`` and predicted poses ``predicted[k] (N, 3)``, drawing from ``rngs[k]``
    (``systems``: :class:`~parcover_env.localization.kinect.system.KinectSystem` s, typed ``Any`` because
    ``system`` imports this module). ``ticks (K, S)``: a block whose row ``k`` IS system ``k``'s
    ``next_tick`` (shared rows, updated in place); None: gathered here and written back."""
    out: list[dict[int, np.ndarray]] = [{} for _ in systems]
    k_count = len(systems)
    shared = ticks is not None or k_count == 1
    if ticks is None:  # K = 1: the system's own array, updated in place
        ticks = stack([s.next_tick for s in systems])
    scratch = _scratch(ticks.shape, true.shape[1])
    due, active = scratch.due, scratch.active
    true = np.ascontiguousarray(true, dtype=float)
    markers = np.ascontiguousarray(markers, dtype=bool)
    finite = batch_kernels.schedule(ticks, np.asarray(times, dtype=float), systems[0].periods, markers, true, due,
                                    active)
    models = [s.fast for s in systems]
    on = active.tolist()
    for k, s in enumerate(systems):
        if not shared:
            s.next_tick[:] = ticks[k]
        s.last_fixes = {}
        if on[k] and models[k] is None:  # kinect: frames
            per_kinect = s.frame_estimates(np.flatnonzero(due[k]), true[k], markers[k], rngs[k], times[k])
            out[k] = s.track(per_kinect, markers[k], predicted[k], times[k])
    batch = [k for k, (model, o) in enumerate(zip(models, on, strict=True)) if o and model is not None]
    if len(batch) == k_count and _tables(models).shared:  # every world, one set of Kinect scenes: one group
        groups = {(): batch}
    else:  # worlds sharing the static Kinect scenes (the batched worlds do) go together
        groups = {}
        for k in batch:
            groups.setdefault(tuple(map(id, models[k].depths)) if len(batch) > 1 else (), []).append(k)
    for ks in groups.values():
        every = len(ks) == k_count  # all worlds (the common case): no gather
        rows = slice(None) if every else ks
        if not (finite if every else np.isfinite(true[rows]).all()):
            for k in ks:
                check_poses(true[k], markers[k])  # the ValueError naming what is wrong
        group, when = (systems, times) if every else ([systems[k] for k in ks], [times[k] for k in ks])
        found = _detections(group, due[rows], true[rows], markers[rows], when, rngs if every else [rngs[k] for k in ks],
                            scratch)
        fixes = track_all(group, found, markers[rows], predicted[rows], when, scratch)
        for k, f in zip(ks, fixes, strict=True):
            out[k] = f
    return out


class Detections(NamedTuple):
    """The detections of one step's due Kinects in ``B`` worlds, world by world (each in its
    Kinects' order): flat lists, one entry per detection."""

    world: list[int]
    """The world (``0 .. B - 1``) of each detection, ascending."""
    kinect: list[int]
    """The Kinect that saw it (index into the system's sensors)."""
    robot: list[int]
    """The carrier it was sampled from (do not use for association)."""
    pose: list[tuple[float, float, float]]
    """The estimated pose ``(x, y, theta)``."""
    n_markers: int
    """The markers of every estimate (the pattern's)."""


def fast_estimates(systems: Sequence[Any], due: np.ndarray, true: np.ndarray, markers: np.ndarray,
                   times: Sequence[float], rngs: Sequence[np.random.Generator]) -> list[list[PoseEstimate]]:
    """The estimate model of the due Kinects (``due (B, S)`` bool) of ``B`` systems (their estimate
    models share one set of static depths) at true poses ``true[b] (N, 3)`` of the carriers
    ``markers[b] (N,)``: per system, the estimates of its due Kinects in their order (as
    :meth:`~parcover_env.localization.kinect.estimate_model.FastModel.estimate`, one list)."""
    found = _detections(systems, due, true, markers, times, rngs)
    return [_estimates(systems[0], found, range(len(found.world)), times) if len(systems) == 1 else
            _estimates(systems[b], found, [d for d, w in enumerate(found.world) if w == b], times)
            for b in range(len(systems))]


def _estimates(system: Any, found: Detections, which: Sequence[int], times: Sequence[float]) -> list[PoseEstimate]:
    """The detections ``which`` (indices into ``found``) of ``system`` as PoseEstimates."""
    names = [s.name for s in system.fast.sensors]
    return [PoseEstimate(*found.pose[d], found.n_markers, kinect=names[found.kinect[d]],
                         stamp=times[found.world[d]], truth_index=found.robot[d]) for d in which]


def _detections(systems: Sequence[Any], due: np.ndarray, true: np.ndarray, markers: np.ndarray,
                times: Sequence[float], rngs: Sequence[np.random.Generator],
                scratch: Scratch | None = None) -> Detections:
    """:func:`fast_estimates` as flat lists (every world's draws, in its order); ``scratch``: the
    buffers of :func:`_scratch` for at least these worlds (made here if None)."""
    models = [s.fast for s in systems]
    kinects, pattern, _ = _tables(models)
    if scratch is None:
        scratch = _scratch(due.shape, true.shape[1])
    cands = scratch.candidates
    n_rows, n = batch_kernels.due_candidates(
        np.ascontiguousarray(due, dtype=bool), np.ascontiguousarray(true, dtype=float),
        np.ascontiguousarray(markers, dtype=bool), kinects, pattern, models[0].depths, models[0].noise, *cands)
    drop, world, depth = cands.drop[:n_rows].tolist(), cands.index[n_rows:2 * n_rows].tolist(), \
        cands.index[2 * n_rows:3 * n_rows].tolist()
    cand_row, cand_index, geom = cands.row[:n].tolist(), cands.robot[:n].tolist(), cands.geom[:n].tolist()
    found = Detections([], [], [], [], pattern.shape[1])
    c = 0
    # the rows that draw: every row where frames drop, else only those with candidates (in order)
    for r in range(len(drop)) if max(drop, default=0.0) > 0.0 else dict.fromkeys(cand_row):
        b, q = world[r], depth[r]
        rng = rngs[b]
        dropped = drop[r] > 0.0 and rng.random() < drop[r]
        while c < n and cand_row[c] == r:
            i = cand_index[c]
            p_det, merged, sigma_xy, sigma_th, x, y, th = geom[c]
            c += 1
            if dropped or merged or rng.random() >= p_det:
                continue  # the frame dropped, the markers merged, or too small to be found
            z = rng.standard_normal(3).tolist()  # as rng.normal(0, sigma) three times
            found.world.append(b)
            found.kinect.append(q)
            found.robot.append(i)
            found.pose.append((x + (0.0 + sigma_xy * z[0]), y + (0.0 + sigma_xy * z[1]),
                               wrap(th + (0.0 + sigma_th * z[2]))))
    return found


class Scratch(NamedTuple):
    """Buffers of one :func:`update_systems` call of ``K`` worlds with ``S`` Kinects and ``N`` robots,
    reused from call to call (their values are read out before the call returns)."""

    due: np.ndarray
    """``(K, S)`` bool: the Kinects due."""
    active: np.ndarray
    """``(K,)`` bool: the worlds with a due Kinect and a carrier."""
    candidates: batch_kernels.CandidateRows
    """``K S`` rows and ``K S N`` candidates."""
    tracks: track_kernel.TrackRows
    """``K S N`` detections of ``K`` worlds."""


_SCRATCH = threading.local()
"""Per thread: the last :class:`Scratch` by shape ``(K, S, N)``."""


def _scratch(shape: tuple[int, ...], n_robots: int) -> Scratch:
    """The :class:`Scratch` of ``shape = (K, S)`` Kinects and ``n_robots`` robots (made once per shape)."""
    key = (*shape, n_robots)
    held = getattr(_SCRATCH, "held", None)
    if held is None or held[0] != key:
        k, s = shape
        held = _SCRATCH.held = (key, Scratch(np.empty(shape, dtype=bool), np.empty(k, dtype=bool),
                                             batch_kernels.candidate_rows(k * s, k * s * n_robots),
                                             track_kernel.track_scratch(k * s * n_robots, k)))
    return held[1]


class Tables(NamedTuple):
    """The estimate models' constants of ``K`` worlds, model after model (:func:`_tables`)."""

    kinects: np.ndarray
    """Their :data:`~parcover_env.localization.kinect.estimate_kernel.KINECT` rows."""
    pattern: np.ndarray
    """Their Kinects' marker patterns."""
    shared: bool
    """True if every model has the same static depths (the same arrays: one group of worlds)."""


_TABLES: list = []
"""The models last stacked (kept alive, so compared by identity: a model's tables are made once, and
the batched worlds' models change only when a world remounts its Kinects, a reset) and their
:class:`Tables`."""


def _tables(models: Sequence[Any]) -> Tables:
    """The :class:`Tables` of the estimate ``models`` (their Kinects, model after model)."""
    if len(models) == 1:
        return Tables(models[0].kinects, models[0].pattern, True)
    if _TABLES and len(_TABLES[0]) == len(models) and all(map(is_, models, _TABLES[0])):
        return _TABLES[1]
    # structured rows concatenated as bytes (numpy's field promotion costs ~2 us a table)
    kinects = np.concatenate([m.kinects.view(np.uint8) for m in models]).view(estimate_kernel.KINECT)
    pattern = np.concatenate([m.pattern for m in models])
    depths = models[0].depths
    shared = all(len(m.depths) == len(depths) and all(map(is_, m.depths, depths)) for m in models)
    _TABLES[:] = [list(models), Tables(kinects, pattern, shared)]
    return _TABLES[1]


def track_all(systems: Sequence[Any], found: Detections, markers: np.ndarray, predicted: np.ndarray,
              times: Sequence[float], scratch: Scratch | None = None) -> list[dict[int, np.ndarray]]:
    """:meth:`KinectSystem.track <parcover_env.localization.kinect.system.KinectSystem.track>` of ``B``
    systems (one scenario) for their ``found`` detections, carriers ``markers (B, N)`` and predicted
    poses ``predicted (B, N, 3)``: every world's fusion and matching in one compiled call
    (:func:`~parcover_env.localization.kinect.track_kernel.match`), a world outside its common
    case through its own tracker; the same fixes (and tracker state) as ``track`` of each."""
    b_count = len(systems)
    t = systems[0].tracking
    ref = np.stack([s.references(p) for s, p in zip(systems, predicted, strict=True)]) \
        if any(s.handover for s in systems) else predicted
    e = len(found.world)
    out = scratch.tracks if scratch is not None and scratch.tracks.robot.shape[0] >= e \
        and scratch.tracks.status.shape[0] >= b_count else track_kernel.track_scratch(e, b_count)
    track_kernel.track_rows(
        np.array(found.world, dtype=np.int64), np.array(found.pose, dtype=float).reshape(-1, 3),
        float(found.n_markers), np.asarray(ref, dtype=float), np.ascontiguousarray(markers, dtype=bool),
        float(t.gate), float(t.fuse_radius), *out)
    bounds, robots, flagged = out.starts[:b_count + 1].tolist(), out.robot[:e].tolist(), out.status[:b_count].tolist()
    poses = list(out.fused[:e].copy())  # the fixes keep their rows: not the scratch's
    out = []
    for b, s in enumerate(systems):
        lo, hi = bounds[b], bounds[b + 1]
        if flagged[b]:  # outside the common case: the system's own tracking
            out.append(s.track([_estimates(s, found, range(lo, hi), times)], markers[b], predicted[b], times[b]))
            continue
        fixes = s.tracker.assign(poses[lo:hi], robots[lo:hi], times[b])
        if s.handover:
            s.tracked(fixes, markers[b])
        else:  # what tracked does without robots awaiting their first detection
            s.last_fixes = fixes
        out.append(fixes)
    return out
