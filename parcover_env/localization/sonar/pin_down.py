"""Does a scan pin a localized pose down? The shift test on a 360-degree sonar scan.

A scan of open space (mostly no echo) or along a straight corridor matches the known map about as
well from a pose shifted along the free direction: the localizer's pose is then a guess along it,
whatever its own scan error says. :func:`shift_increase` measures how much worse the scan matches
the known map's synthetic scans from the pose shifted by a fixed distance in ``n_dirs`` directions
(heading kept); a fix is informative when the smallest increase exceeds a threshold
(``observation.scan.min_shift_increase`` in the env's service, ``expert.sonar_fix`` in the
expert's own loop).
"""

from __future__ import annotations

import math

import numpy as np

from parcover_env.config import SonarConfig
from parcover_env.localization.sonar.localizer import scan_error
from parcover_env.sensors.sonar import simulate_beams

__all__ = ["shift_increase", "shifted_errors"]


def shifted_errors(ranges: np.ndarray, scan_angles: np.ndarray, pose: np.ndarray, *, segments: np.ndarray,
                   sonar: SonarConfig, others: np.ndarray, radius: float, clip: float, step: float,
                   trim: float = 0.0, n_dirs: int = 8) -> np.ndarray:
    """Scan errors ``(1 + n_dirs,)`` (m) of ``ranges`` (one per ``scan_angles``, robot frame) against
    the synthetic scans of the walls ``segments (S, 4)`` with the teammates ``others (M, 2)`` as discs
    of ``radius``, from ``pose (3,)`` and from ``pose`` shifted by ``step`` (m) in ``n_dirs`` evenly
    spaced directions (heading kept); mean absolute error clipped at ``clip`` (m) over the best
    ``1 - trim`` share of the readings (:func:`~parcover_env.localization.sonar.localizer.scan_error`).
    Measure with the trim of the error that accepts the fix: a scan with few echoes matches
    perfectly once its few informative readings are trimmed, wherever it is."""
    ang = np.arange(n_dirs) * (2 * math.pi / n_dirs)
    origins = np.vstack([pose[:2], pose[:2] + step * np.c_[np.cos(ang), np.sin(ang)]])
    axes = np.broadcast_to(pose[2] + np.asarray(scan_angles, dtype=float), (len(origins), len(scan_angles)))
    synth = simulate_beams(sonar, origins, np.ascontiguousarray(axes), segments,
                           np.asarray(others, dtype=float).reshape(-1, 2), radius, np.full(len(origins), -1))
    return scan_error(ranges, synth, clip, trim)


def shift_increase(errors: np.ndarray) -> float:
    """How well a scan pins a pose down: ``errors (1 + K,)`` from :func:`shifted_errors`; returns the
    smallest increase over the K shifts (m). Near 0 along a straight corridor or in open space."""
    e = np.asarray(errors, dtype=float)
    return float(np.min(e[1:]) - e[0])
