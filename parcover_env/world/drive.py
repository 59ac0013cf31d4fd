"""Differential-drive dynamics: unicycle commands -> wheel-speed targets -> lagged wheel speeds.

Pure, batched numpy over robots. The state of the drive is each robot's left and right wheel
ground speed (m/s); ``DiffDrive`` keeps it in plain arrays (it pickles and deep-copies as is).
"""

from __future__ import annotations

import math

import numpy as np

from parcover_env.config import DriveConfig
from parcover_env.world.batching import stack

__all__ = ["DiffDrive", "wheel_targets", "lag_step", "body_velocity", "advance_steps_all", "command_steps_all",
           "command_steps_rows", "take_travel_all"]


def wheel_targets(commands: np.ndarray, wheel_base: float, wheel_speed_max: float) -> np.ndarray:
    """Unicycle commands ``(N, 2)`` (v m/s, omega rad/s) -> wheel-speed targets ``(N, 2)`` (left, right).

    ``v_L = v - omega b / 2``, ``v_R = v + omega b / 2``; a pair whose larger magnitude exceeds
    ``wheel_speed_max`` is scaled down by one common factor, which keeps the path's curvature.
    """
    c = np.asarray(commands, dtype=float)
    half = 0.5 * wheel_base * c[:, 1]
    out = np.empty((len(c), 2))
    np.subtract(c[:, 0], half, out=out[:, 0])
    np.add(c[:, 0], half, out=out[:, 1])
    peak = np.maximum(np.abs(out[:, 0]), np.abs(out[:, 1]))
    scale = np.minimum(1.0, wheel_speed_max / np.maximum(peak, 1e-300))
    out *= scale[:, None]
    return out


def lag_step(wheels: np.ndarray, targets: np.ndarray, tau: float, accel_max: float, dt: float) -> np.ndarray:
    """Wheel speeds after ``dt``: the exact first-order lag towards ``targets`` (time constant
    ``tau``), its change clipped to ``accel_max * dt`` (bounded wheel acceleration)."""
    gain = -math.expm1(-dt / tau)  # 1 - exp(-dt / tau), accurate for small dt / tau
    dv = np.clip((targets - wheels) * gain, -accel_max * dt, accel_max * dt)
    return wheels + dv


def body_velocity(wheels: np.ndarray, wheel_base: float) -> np.ndarray:
    """Wheel speeds ``(N, 2)`` (left, right) -> body ``(v, omega)`` ``(N, 2)``."""
    left, right = wheels[:, 0], wheels[:, 1]
    return np.stack([0.5 * (left + right), (right - left) / wheel_base], axis=1)


class DiffDrive:
    """The wheels of ``n`` robots. ``advance`` runs once per physics step.

    Attributes (all ``(n, 2)``, columns left, right): ``wheels`` the wheel ground speeds (m/s),
    ``travel`` each wheel's signed distance since the last ``take_travel`` (m).
    """

    def __init__(self, cfg: DriveConfig, n: int):
        self.cfg = cfg
        self.wheels = np.zeros((n, 2))
        self.travel = np.zeros((n, 2))
        self.speed_change = np.zeros((n, 2))
        """Sum of |speed changes| of each wheel since the last ``take_travel`` (m/s)."""

    def advance(self, targets: np.ndarray, dt: float) -> np.ndarray:
        """One physics step: the wheels move the body at their current speeds for ``dt`` (pymunk
        integrates positions with the velocity set at the previous step), then follow ``targets``.
        Returns the new body velocities ``(n, 2)`` (v, omega) to apply."""
        c = self.cfg
        self.travel += self.wheels * dt
        new = lag_step(self.wheels, targets, c.tau, c.accel_max, dt)
        self.speed_change += np.abs(new - self.wheels)
        self.wheels = new
        return body_velocity(new, c.wheel_base)

    def advance_steps(self, targets: np.ndarray, dt: float, steps: int) -> np.ndarray:
        """``steps`` calls of :meth:`advance` towards the same ``targets`` in one compiled loop (the
        same floats); returns the body velocities ``(steps, n, 2)`` of each call."""
        return advance_steps_all([self], np.asarray(targets, dtype=float)[None], dt, steps)[:, 0]

    def take_travel(self) -> tuple[np.ndarray, np.ndarray]:
        """Wheel distances (m) and summed |speed changes| (m/s), each ``(n, 2)``, since the last call;
        resets both (the odometry reads them once per control step)."""
        travel, change = self.travel, self.speed_change
        self.travel = np.zeros_like(travel)
        self.speed_change = np.zeros_like(change)
        return travel, change


def advance_steps_all(drives: list[DiffDrive], targets: np.ndarray, dt: float, steps: int) -> np.ndarray:
    """:meth:`DiffDrive.advance_steps` of ``K`` drives of ``n`` robots each (one configuration), in one
    compiled loop over all ``K n`` robots: ``targets`` ``(K, n, 2)``; returns the body velocities
    ``(steps, K, n, 2)`` (a view). Each drive's state is gathered, advanced and written back in place:
    drive ``k`` ends as if it had been advanced alone (the same floats)."""
    return _advance_all(drives, targets, dt, steps, None).transpose(2, 0, 1, 3)


def command_steps_all(drives: list[DiffDrive], commands: np.ndarray, dt: float, steps: int) -> np.ndarray:
    """:func:`advance_steps_all` towards the :func:`wheel_targets` of the unicycle ``commands``
    ``(K, n, 2)`` (within the drives' ``wheel_speed_max``), the targets computed in the same
    compiled call (the same floats); the body velocities robot by robot: ``(K, n, steps, 2)``
    (C-contiguous, as :func:`~parcover_env.world.physics.step_all` takes them)."""
    return _advance_all(drives, commands, dt, steps, drives[0].cfg.wheel_speed_max)


def command_steps_rows(cfg: DriveConfig, wheels: np.ndarray, travel: np.ndarray, speed_change: np.ndarray,
                       commands: np.ndarray, dt: float, steps: int) -> np.ndarray:
    """:func:`command_steps_all` of ``K`` drives of ``n`` robots each (configuration ``cfg``) whose
    state is held as rows of C-contiguous float64 blocks ``wheels``, ``travel`` and
    ``speed_change`` ``(K, n, 2)``, advanced in place (no gather, no scatter); returns the body
    velocities ``(K, n, steps, 2)``."""
    k, n = wheels.shape[:2]
    out = _advance(cfg, wheels.reshape(k * n, 2), travel.reshape(k * n, 2), speed_change.reshape(k * n, 2),
                   commands, dt, steps, cfg.wheel_speed_max)
    return out.reshape(k, n, steps, 2)


_KERNELS: list = []


def _advance(cfg: DriveConfig, wheels: np.ndarray, travel: np.ndarray, change: np.ndarray, block: np.ndarray,
             dt: float, steps: int, wheel_speed_max: float | None) -> np.ndarray:
    """The compiled drive steps on the flat state ``(M, 2)`` in place, towards ``block``: wheel targets,
    or unicycle commands when ``wheel_speed_max`` is given; the body velocities ``(M, steps, 2)``."""
    if not _KERNELS:  # numba is imported on first use
        from parcover_env.world import drive_kernels

        _KERNELS.append(drive_kernels)
    drive_kernels = _KERNELS[0]
    gain = -math.expm1(-dt / cfg.tau)
    out = np.empty((len(wheels), steps, 2))
    flat = np.ascontiguousarray(block, dtype=float).reshape(len(wheels), 2)
    if wheel_speed_max is None:
        drive_kernels.lag_steps(wheels, travel, change, flat, gain, cfg.accel_max * dt, dt, cfg.wheel_base, out)
    else:
        drive_kernels.command_steps(flat, float(wheel_speed_max), wheels, travel, change, gain, cfg.accel_max * dt, dt,
                                    cfg.wheel_base, out)
    return out


def _advance_all(drives: list[DiffDrive], block: np.ndarray, dt: float, steps: int,
                 wheel_speed_max: float | None) -> np.ndarray:
    """The body velocities ``(K, n, steps, 2)`` of the drives advanced towards ``block`` ``(K, n, 2)``:
    wheel targets, or unicycle commands when ``wheel_speed_max`` is given (gathered and scattered)."""
    k, n = block.shape[:2]
    if k == 1:  # one drive: its own arrays, no gather
        wheels, travel, change = drives[0].wheels.copy(), drives[0].travel, drives[0].speed_change
    else:
        wheels = np.concatenate([d.wheels for d in drives])
        travel = np.concatenate([d.travel for d in drives])
        change = np.concatenate([d.speed_change for d in drives])
    out = _advance(drives[0].cfg, wheels, travel, change, block, dt, steps, wheel_speed_max)
    if k == 1:
        drives[0].wheels = wheels
    else:  # scatter each drive's rows back
        for j, d in enumerate(drives):
            rows = slice(j * n, (j + 1) * n)
            d.wheels = wheels[rows].copy()
            d.travel[:] = travel[rows]
            d.speed_change[:] = change[rows]
    return out.reshape(k, n, steps, 2)


def take_travel_all(drives: list[DiffDrive]) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`DiffDrive.take_travel` of ``K`` drives of ``n`` robots each: their wheel distances and
    summed |speed changes| as two ``(K, n, 2)`` blocks (copies); each drive's own arrays are
    zeroed in place."""
    travel = stack([d.travel for d in drives], copy=True)
    change = stack([d.speed_change for d in drives], copy=True)
    for d in drives:
        d.travel.fill(0.0)
        d.speed_change.fill(0.0)
    return travel, change
