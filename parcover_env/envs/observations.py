"""Per-agent observation vector: a named, fixed layout with physical bounds (SI units)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from parcover_env.config import Scenario
from parcover_env.envs.feature_sets import feature_set
from parcover_env.envs.obs_spec import ENTRIES, KERNEL_COLUMNS, KERNEL_ENTRIES, MAX_FIX_AGE
from parcover_env.geometry import atan2
from parcover_env.sensors.base import Sensor
from parcover_env.sim.pipeline import ScalarInputs

__all__ = ["ObservationLayout", "MAX_FIX_AGE", "SCALAR_ENTRIES", "ScalarInputs", "build_sensors", "ellipse_entries"]

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
        from parcover_env.envs import obs_kernels as step_kernels

        rows = step_kernels.RobotRows(*inputs[:10])
        step_kernels.scalar_entries_many(obs, self.columns, rows, float(max(obs.shape[1] - 1, 1)), MAX_FIX_AGE,
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
