"""Per-agent observation vector: a named, fixed layout with physical bounds (SI units), and the
compiled (numba) pass writing its scalar entries of every robot of ``K`` worlds
(:func:`scalar_entries_many`: the same float operations, in the same order, as the numpy formulas
they replace; ``tests/envs/test_observation_assembly.py`` keeps the reference)."""


from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from gymnasium import spaces
from numba import njit

from parcover_env.config import Scenario
from parcover_env.envs.feature_sets import feature_set
from parcover_env.envs.obs_spec import ENTRIES, KERNEL_COLUMNS, KERNEL_ENTRIES, MAX_FIX_AGE
from parcover_env.geometry import atan2
from parcover_env.sensors.base import Sensor
from parcover_env.sim.pipeline import ScalarInputs

__all__ = ["ObservationLayout", "MAX_FIX_AGE", "SCALAR_ENTRIES", "ScalarInputs", "build_sensors", "ellipse_entries",
           "RobotRows", "scalar_entries", "scalar_entries_many"]


SCALAR_ENTRIES = KERNEL_ENTRIES
"""The one-column entries :meth:`ObservationLayout.fill_scalars` writes (all but the sensors')."""


def ellipse_entries(cov: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Pose covariances ``(N, 3, 3)`` -> ``(N, 5)``: sigma_major, sigma_minor (m), the major axis'
    doubled angle in the robot frame as (cos 2a, sin 2a) (an axis has no sign; (1, 0) for a
    circle), and the heading sigma (rad). ``heading``: the estimated headings ``(N,)``."""
    a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    mean, half = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
    two_a = np.where(half <= 1e-9 * mean, 0.0, atan2(2.0 * b, a - c) - 2.0 * heading)
    return np.stack([np.sqrt(np.maximum(mean + half, 0.0)), np.sqrt(np.maximum(mean - half, 0.0)),
                     np.cos(two_a), np.sin(two_a), np.sqrt(np.maximum(cov[:, 2, 2], 0.0))], axis=1)


@dataclass(frozen=True)
class ObservationLayout:
    """Names, slices and bounds of the entries of one agent's observation."""

    names: tuple[str, ...]
    slices: dict[str, slice]
    low: np.ndarray
    high: np.ndarray

    @classmethod
    def build(cls, scenario: Scenario, box, sensors: dict[str, Sensor | None] | None = None) -> ObservationLayout:
        """The layout of ``scenario`` on a map of bounds ``box`` from the spec
        (:data:`~parcover_env.envs.obs_spec.ENTRIES`); ``sensors``: the built sensor of each
        ``sensor`` entry (None = off; built from the scenario if not given)."""
        sensors = sensors if sensors is not None else build_sensors(scenario)
        sources = feature_set(scenario.observation.version).sources  # the entries of the scenario's version
        names, slices, low, high, at = [], {}, [], [], 0
        for e in ENTRIES:
            size = e.n_columns(scenario, sensors.get(e.name), sources)
            if size == 0:
                continue
            lo, hi = e.bounds(scenario, tuple(box))
            names.append(e.name)
            slices[e.name] = slice(at, at + size)
            low += [lo] * size
            high += [hi] * size
            at += size
        return cls(tuple(names), slices, np.array(low, np.float32), np.array(high, np.float32))

    @property
    def size(self) -> int:
        return len(self.low)

    def space(self) -> spaces.Box:
        return spaces.Box(self.low, self.high, dtype=np.float32)

    def clip(self, obs: np.ndarray) -> np.ndarray:
        """Clip observations ``(..., D)`` (one world's ``(N, D)``, ``K`` worlds' ``(K, N, D)``) into the
        bounds in place (NaN stays NaN, as with ``np.clip``)."""
        return np.minimum(np.maximum(obs, self.low, out=obs), self.high, out=obs)

    def fill_scalars(self, obs: np.ndarray, inputs: ScalarInputs) -> None:
        """Write the :data:`SCALAR_ENTRIES` of every robot's row of ``obs (N, D)`` in one compiled
        pass: the pose estimate, encoder velocity, leader flag, slot (scaled by ``N - 1``), seconds
        since the last fix (capped at :data:`MAX_FIX_AGE`), the ellipse of the covariance
        (:func:`ellipse_entries`), the lookahead goal in the robot frame, the follower camera's
        reading and the two team-wide fractions. The one-world call of :meth:`fill_scalars_many`."""
        self.fill_scalars_many(obs[None], ScalarInputs(*(np.asarray(x)[None] for x in inputs)))

    def fill_scalars_many(self, obs: np.ndarray, inputs: ScalarInputs) -> None:
        """:meth:`fill_scalars` of ``K`` worlds in one compiled call: ``obs (K, N, D)``, every field of
        ``inputs`` with a leading ``K`` axis (the two fractions ``(K,)``)."""
        rows = RobotRows(*inputs[:10])
        scalar_entries_many(obs, self.columns, rows, float(max(obs.shape[1] - 1, 1)), MAX_FIX_AGE,
                                         np.asarray(inputs.kpois_visited, dtype=float),
                                         np.asarray(inputs.time, dtype=float))

    @property
    def columns(self) -> np.ndarray:
        """The column of each :data:`SCALAR_ENTRIES` entry (-1: not in this layout), a one-element
        read-only :data:`~parcover_env.envs.obs_spec.KERNEL_COLUMNS` record."""
        cols = self.__dict__.get("_cols")
        if cols is None:  # frozen dataclass: cache by the back door
            cols = np.array([tuple(self.slices[k].start if k in self.slices else -1 for k in KERNEL_ENTRIES)],
                            dtype=KERNEL_COLUMNS)
            cols.setflags(write=False)
            object.__setattr__(self, "_cols", cols)
        return cols

    def get(self, obs: np.ndarray, name: str) -> np.ndarray:
        """The entry ``name`` of one observation ``(D,)`` or a batch ``(N, D)``."""
        return obs[..., self.slices[name]]


def build_sensors(scenario: Scenario) -> dict[str, Sensor | None]:
    """The sensor of every ``sensor`` entry of the spec, built from ``scenario`` (None = off)."""
    return {e.name: e.sensor(scenario) for e in ENTRIES if e.sensor is not None}


class RobotRows(NamedTuple):
    """Per-robot inputs of :func:`scalar_entries` (the first ten fields of
    :class:`~parcover_env.sim.pipeline.ScalarInputs`)."""

    est: np.ndarray
    vel: np.ndarray
    leader: np.ndarray
    slot: np.ndarray
    fix_age: np.ndarray
    cov: np.ndarray
    goals: np.ndarray
    rel_xy: np.ndarray
    rel_heading: np.ndarray
    visible: np.ndarray


@njit(cache=True, nogil=True)
def _put(out, i, col, value):
    if col >= 0:
        out[i, col] = value


@njit(cache=True, nogil=True)
def scalar_entries(out, cols, r, slot_div, max_fix_age, kpois, time):
    """Write the non-sensor entries of every robot's observation row ``out (N, D)``: ``cols`` a
    one-element :data:`~parcover_env.envs.obs_spec.KERNEL_COLUMNS` record (each entry's column by
    name, -1 = absent), ``r`` the :class:`RobotRows`, slots divided by ``slot_div``, fix ages capped
    at ``max_fix_age``, and the team's ``kpois`` and ``time`` fractions."""
    col = cols[0]
    for i in range(out.shape[0]):
        th = r.est[i, 2]
        a, b, c = r.cov[i, 0, 0], r.cov[i, 0, 1], r.cov[i, 1, 1]
        mean = 0.5 * (a + c)
        half = math.hypot(0.5 * (a - c), b)
        two_a = 0.0 if half <= 1e-9 * mean else math.atan2(2.0 * b, a - c) - 2.0 * th
        gx = r.goals[i, 0] - r.est[i, 0]
        gy = r.goals[i, 1] - r.est[i, 1]
        cr = math.cos(-th)
        sr = math.sin(-th)
        seen = r.visible[i]
        _put(out, i, col.x, r.est[i, 0])
        _put(out, i, col.y, r.est[i, 1])
        _put(out, i, col.cos_theta, math.cos(th))
        _put(out, i, col.sin_theta, math.sin(th))
        _put(out, i, col.v, r.vel[i, 0])
        _put(out, i, col.omega, r.vel[i, 1])
        _put(out, i, col.leader, 1.0 if r.leader[i] else 0.0)
        _put(out, i, col.slot, r.slot[i] / slot_div)
        _put(out, i, col.fix_age, min(r.fix_age[i], max_fix_age))
        _put(out, i, col.sigma_major, math.sqrt(max(mean + half, 0.0)))
        _put(out, i, col.sigma_minor, math.sqrt(max(mean - half, 0.0)))
        _put(out, i, col.sigma_axis_cos2, math.cos(two_a))
        _put(out, i, col.sigma_axis_sin2, math.sin(two_a))
        _put(out, i, col.sigma_heading, math.sqrt(max(r.cov[i, 2, 2], 0.0)))
        _put(out, i, col.goal_dx, cr * gx - sr * gy)
        _put(out, i, col.goal_dy, sr * gx + cr * gy)
        _put(out, i, col.pred_dx, r.rel_xy[i, 0])
        _put(out, i, col.pred_dy, r.rel_xy[i, 1])
        _put(out, i, col.pred_cos, math.cos(r.rel_heading[i]) if seen else 0.0)
        _put(out, i, col.pred_sin, math.sin(r.rel_heading[i]) if seen else 0.0)
        _put(out, i, col.pred_visible, 1.0 if seen else 0.0)
        _put(out, i, col.kpois_visited, kpois)
        _put(out, i, col.time, time)


@njit(cache=True, nogil=True)
def scalar_entries_many(out, cols, r, slot_div, max_fix_age, kpois, time):
    """:func:`scalar_entries` of ``K`` worlds: ``out (K, N, D)``, the :class:`RobotRows` fields
    ``(K, N, ...)``, the team fractions ``kpois`` and ``time`` ``(K,)``."""
    for k in range(out.shape[0]):
        rows = RobotRows(r.est[k], r.vel[k], r.leader[k], r.slot[k], r.fix_age[k], r.cov[k], r.goals[k], r.rel_xy[k],
                         r.rel_heading[k], r.visible[k])
        scalar_entries(out[k], cols, rows, slot_div, max_fix_age, kpois[k], time[k])
