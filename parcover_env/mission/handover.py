"""Alg. 1 of Min, Fehr & Papanikolopoulos, the env's side: split groups at their turning points on
the Kinect system's detections, and hand the promoted followers over to the Kinect system.

The Kinect system splits a group when it detects its leader at the TP (:meth:`Team.update`); a
leader out of every footprint splits on its own estimate. A follower promoted by a split carries
no fix yet: the Kinect system locates it by the formation, i.e. the pose of the robot ahead
composed with the follower camera's last measurement of it (:func:`handover_poses`). That
measurement is an explicit input here (:class:`CameraView`, what the stepper's last ``observe``
measured), not state read behind the caller's back.

:func:`update_teams` does this for ``K`` worlds: a few array operations over ``(K, N)`` find the
worlds where some group leader may have reached its TP (by its estimate, its plan progress or a
Kinect fix this step); only those run :func:`update_team` (splits are rare events), the others
would not change.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from parcover_env.localization.kinect.system import KinectSystem, handover_poses
from parcover_env.mission.team import Team
from parcover_env.sensors.relative import RelativeReading

__all__ = ["CameraView", "SPLIT_MARGIN", "update_team", "update_teams"]

SPLIT_MARGIN = 1e-9
"""How much :func:`update_teams` widens its tests (m) so that a last-bit difference between its
compiled distances and :meth:`Team.update`'s numpy ones can never skip a split."""


class CameraView(NamedTuple):
    """The follower cameras' measurements of one observation, with what they were taken against
    (of one world; or of ``K`` worlds as ``(K, N, ...)`` blocks, whose world ``k`` is :meth:`select` ``(k)``)."""

    predecessor: np.ndarray
    """``(N,)`` the robot each robot followed when measured (-1 none)."""
    reading: RelativeReading
    """The cameras' reading then."""
    estimates: np.ndarray
    """The pose estimates ``(N, 3)`` then."""

    def select(self, k: int | slice) -> CameraView:
        """Of a view of ``K`` worlds: world ``k``'s view (or the worlds of the slice ``k``), views of its arrays."""
        r = self.reading
        return CameraView(self.predecessor[k], RelativeReading(r.rel_xy[k], r.rel_heading[k], r.visible[k]),
                          self.estimates[k])


def update_team(team: Team, kinects: KinectSystem | None, estimate: np.ndarray, plan_progress: np.ndarray,
                view: CameraView | None) -> None:
    """Split every group whose leader reached its TP (detected by ``kinects``, or on its estimate);
    the promoted followers are handed to ``kinects`` at the poses ``view`` gives them."""
    est = estimate[:, :2]
    if kinects is None:
        team.update(est, plan_progress)
        return
    before, fixes = team.leader.copy(), kinects.last_fixes  # a split writes the team's arrays in place
    in_view = np.zeros(team.n, dtype=bool)  # read for leaders without a fix only
    unfixed = [i for i in np.flatnonzero(before).tolist() if i not in fixes]
    if unfixed:
        in_view[unfixed] = kinects.in_view(est[unfixed])
    if team.update(est, plan_progress, fixes, in_view) and view is not None:
        promoted = team.leader & ~before
        rel = view.reading
        kinects.hand_over(handover_poses(promoted, view.predecessor, rel.rel_xy, rel.rel_heading, rel.visible,
                                         view.estimates), view.estimates)


def update_teams(teams: Sequence[Team], kinects: Sequence[KinectSystem | None], estimates: np.ndarray,
                 plan_progress: np.ndarray, view_of: Callable[[int], CameraView | None], *,
                 tp: np.ndarray | None = None) -> list[int]:
    """:func:`update_team` of the teams of ``K`` worlds of one mission (one ``tol``; estimates
    ``(K, N, 3)``, plan progress ``(K, N)``; ``view_of(k)``: world ``k``'s camera view, asked for
    the worlds that may split only), run only for the worlds where a leader heading for a
    TP (:attr:`Team.tp_ahead`) has passed its distance, or its estimate or this step's Kinect fix lies
    within ``tol`` of it (one compiled test of all worlds, widened by :data:`SPLIT_MARGIN`): in every
    other world :meth:`Team.update` would not split (its tests are a subset). ``tp``: the teams'
    :attr:`Team.tp_ahead` ``(K, N, 3)`` if at hand (gathered if not). Returns the worlds that ran
    :func:`update_team` (a split there writes its team's arrays in place)."""
    from parcover_env.mission import kernels as step_kernels

    k = len(teams)
    if tp is None:
        tp = teams[0].tp_ahead[None] if k == 1 else np.array([t.tp_ahead for t in teams])
    fix = np.full((*tp.shape[:2], 2), np.nan)
    found = [(j, i, pose) for j, kin in enumerate(kinects) if kin is not None for i, pose in kin.last_fixes.items()]
    if found:  # this step's Kinect fixes, written in one call
        worlds, robots, poses = zip(*found, strict=True)
        fix[worlds, robots] = np.array(poses)[:, :2]
    maybe = np.empty(k, dtype=bool)
    step_kernels.may_split(tp, np.ascontiguousarray(estimates, dtype=float),
                           np.ascontiguousarray(plan_progress, dtype=float), fix, float(teams[0].tol), SPLIT_MARGIN,
                           maybe)
    ran = np.flatnonzero(maybe).tolist()
    for j in ran:
        update_team(teams[j], kinects[j], estimates[j], plan_progress[j], view_of(j))
    return ran
