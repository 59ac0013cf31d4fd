"""Hand-built situations for the expert's sonar fixes (``expert/sonar_fix.py``) on the tree scenario."""

from __future__ import annotations

import numpy as np

import parcover_env
from parcover_env.expert.config import SonarFixConfig
from parcover_env.expert.sonar_fix import SonarFixer
from parcover_env.sensors.sonar import simulate_beams

ODOM = np.array([1.0, 1.0, 0.0])
STALE = {"fix_age": 100.0, "speed": 0.0, "is_leader": True}
"""A stale leader standing still (``stale_after`` is 8 s)."""


def make_fixer(env_scan: bool = False, **cfg) -> SonarFixer:
    """A fixer on the tree scenario (control step 0.1 s, eight beams 45 degrees apart)."""
    return SonarFixer(parcover_env.load_scenario("tree"), np.radians(np.arange(0, 360, 45.0)), 0.1,
                      SonarFixConfig(**cfg), env_scan=env_scan)


def step(fixer: SonarFixer, odom: np.ndarray = ODOM, **kw):
    """One :meth:`SonarFixer.step` of ``robot_0`` (a stale leader standing still unless ``kw`` says otherwise)."""
    return fixer.step("robot_0", odom, ranges=np.full(len(fixer.beams), 1.0), **{**STALE, **kw})


def ranges_at(fixer: SonarFixer, true: np.ndarray, angles: np.ndarray, mates: np.ndarray | None = None) -> np.ndarray:
    """Noise-free sonar ranges of the tree map from the pose ``true`` along ``angles`` (robot frame),
    teammates (discs of the robot radius) at ``mates (M, 2)``."""
    mates = np.zeros((0, 2)) if mates is None else mates
    return simulate_beams(fixer.sonar, true[None, :2], (true[2] + angles)[None, :], fixer.team.map.segments,
                          mates, fixer.team.radius, np.array([-1]))[0]


def scan_at(fixer: SonarFixer, true: np.ndarray):
    """A noise-free binned 360-degree scan from the pose ``true`` (an object with ``ranges``)."""
    return type("Scan", (), {"ranges": ranges_at(fixer, true, fixer.team.scan_angles)})()
