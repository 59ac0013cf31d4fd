"""Alg. 1 of Min, Fehr & Papanikolopoulos, the env's side: split groups at their turning points on
the Kinect system's detections, and hand the promoted followers over to the Kinect system.

The Kinect system splits a group when it detects its leader at the TP (:meth:`Team.update`); a
leader out of every footprint splits on its own estimate. A follower promoted by a split carries
no fix yet: the Kinect system locates it by the formation, i.e. the pose of the robot ahead
composed with the follower camera's last measurement of it (:func:`handover_poses`). That
measurement is an explicit input here (:class:`CameraView`, what the stepper's last ``observe``
measured), not state read behind the caller's back.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from parcover_env.envs.team import Team
from parcover_env.localization.kinect.system import KinectSystem, handover_poses
from parcover_env.sensors.relative import RelativeReading

__all__ = ["CameraView", "update_team"]


class CameraView(NamedTuple):
    """The follower cameras' measurements of one observation, with what they were taken against."""

    predecessor: np.ndarray
    """``(N,)`` the robot each robot followed when measured (-1 none)."""
    reading: RelativeReading
    """The cameras' reading then."""
    estimates: np.ndarray
    """The pose estimates ``(N, 3)`` then."""


def update_team(team: Team, kinects: KinectSystem | None, estimate: np.ndarray, plan_progress: np.ndarray,
                view: CameraView | None) -> None:
    """Split every group whose leader reached its TP (detected by ``kinects``, or on its estimate);
    the promoted followers are handed to ``kinects`` at the poses ``view`` gives them."""
    est = estimate[:, :2]
    if kinects is None:
        team.update(est, plan_progress)
        return
    before, fixes = team.leader, kinects.last_fixes
    in_view = np.zeros(team.n, dtype=bool)  # read for leaders without a fix only
    unfixed = [i for i in np.flatnonzero(before).tolist() if i not in fixes]
    if unfixed:
        in_view[unfixed] = kinects.in_view(est[unfixed])
    if team.update(est, plan_progress, fixes, in_view) and view is not None:
        promoted = team.leader & ~before
        rel = view.reading
        kinects.hand_over(handover_poses(promoted, view.predecessor, rel.rel_xy, rel.rel_heading, rel.visible,
                                         view.estimates), view.estimates)
