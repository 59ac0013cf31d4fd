"""Tunables of the env's Kinect leader tracker (Min et al.): ``Scenario.kinect_tracking``.

Part of the scenario schema, so a scenario YAML can set them; every field has a unit and is
validated with a ``ConfigError``. The sonar localizer's tunables belong to the localizer
(:mod:`parcover_env.localization.sonar.config`): the env never runs it, the experts do.
"""

from __future__ import annotations

from dataclasses import dataclass

from parcover_env.config.checks import check as _check

__all__ = ["KinectTrackingConfig"]


@dataclass(frozen=True)
class KinectTrackingConfig:
    """Identity tracking of leaders across overhead Kinects (Min et al.)."""

    gate: float = 1.0
    """A Kinect detection is matched to a leader only within this distance of the leader's
    predicted (odometry) pose (m). Wide, so that a leader that drifted on odometry while out of
    view is re-acquired; leaders closer to each other than this rely on the matching's cost."""
    fuse_radius: float = 0.12
    """Detections of overlapping Kinects closer than this are the same robot and are fused (m)."""

    def __post_init__(self) -> None:
        _check(self.gate > 0, "gate", f"must be > 0, got {self.gate}")
        _check(self.fuse_radius > 0, "fuse_radius", f"must be > 0, got {self.fuse_radius}")
        _check(self.fuse_radius < self.gate, "fuse_radius", "must be smaller than the gate")
