"""The Kinect system's side of Min et al., Alg. 1: formation groups, splits at TPs, promotions, messages.

The team leaves the start as one column (robots ordered as in the plan, so every branch's robots
form a contiguous block ``[lo, hi)``). When a group's leader reaches the TP where that group's
robots part, the system splits it: one sub-group per branch, sized by the robots the branch needs,
the first robot of each block leading it (a promotion for every block but the first). Only
leaders talk to the Kinect system; followers keep formation with their own cameras.

Alg. 1 runs "whenever the sensor detects a leader robot": with overhead Kinects, a group splits
when the Kinect system *detects* its leader at the TP (a pose fix this step within ``reach_tol``
of the TP, or past it along the leader's plan path), not on the leader's own estimate. A leader
outside every footprint (by its estimate) keeps going on odometry; if it reaches its TP there, the
split falls back on its estimate and is counted in ``splits["odometry"]`` (without Kinects every
split is such a fallback). ``splits["kinect"]`` counts the splits the Kinect system triggered.

Messages counted by type: ``split`` (to each sub-group at a TP), ``promotion`` (a follower made
leader), ``waypoint`` (next desired position sent to a leader), ``pose`` (a Kinect pose fix sent to
a leader). In ``individual`` mode every robot is its own group: all are localized and messaged.
This is environment infrastructure (what the overhead system does), so RL policies and the
scripted expert observe the same roles; the expert implements the robots' controllers.

:attr:`Team.tp_ahead` lists each group leader's pending TP as numbers, so that the worlds of a batch
can tell in a few array operations which teams may split this step
(:func:`update_teams`); only those run :meth:`Team.update`.

Hand-over (:func:`update_team`): a follower promoted by a split carries
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

from collections import Counter
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from parcover_env.localization.kinect.system import KinectSystem, handover_poses
from parcover_env.planning.plan import Plan
from parcover_env.sensors.relative import RelativeReading

__all__ = ["Team", "TEAM_ROWS", "count_waypoints_many", "CameraView", "SPLIT_MARGIN", "update_team", "update_teams"]

TEAM_ROWS = ("leader", "slot", "predecessor", "tp_ahead")
"""The :class:`Team` arrays the stepper reads for ``K`` worlds as ``(K, N, ...)`` blocks
(:func:`~parcover_env.sim.score_phase.score_blocks`). Made once with the team and never rebound:
a split writes them in place, so a block whose row they are views of stays theirs."""


class Team:
    def __init__(self, plan: Plan, mode: str = "formation", reach_tol: float = 0.2):
        self.n = plan.r
        self.mode = mode
        self.tol = reach_tol
        self.messages: Counter[str] = Counter()
        self.splits: Counter[str] = Counter()
        """Splits by what detected the leader at its TP: ``kinect`` or ``odometry`` (fallback)."""
        self._tps = {tuple(tp.robots): tp for tp in plan.turning_points}
        self.groups: list[tuple[int, int]] = ([(i, i + 1) for i in range(self.n)] if mode == "individual"
                                              else [(0, self.n)])
        self.leader = np.zeros(self.n, dtype=bool)
        """``(N,)`` group leaders."""
        self.slot = np.zeros(self.n, dtype=np.int64)
        """``(N,)`` each robot's place in its group's column (0: the leader)."""
        self.predecessor = np.full(self.n, -1, dtype=np.int64)
        """``(N,)`` the robot each robot follows (-1: none, a leader)."""
        self.tp_ahead = np.full((self.n, 3), np.nan)
        """``(N, 3)``: ``(x, y, distance)`` of the TP each group leader heads for (m; its position
        and its distance along the plan path), NaN for the other robots and in ``individual`` mode."""
        self._refresh()

    def _pending(self) -> None:
        """:attr:`tp_ahead` from the groups and the TPs not passed yet (in place)."""
        self.tp_ahead[...] = np.nan
        if self.mode == "individual":
            return
        for g in self.groups:
            tp = self._tps.get(g)
            if tp is not None:
                self.tp_ahead[g[0]] = (*tp.position, tp.distance)

    def _refresh(self) -> None:
        """The :data:`TEAM_ROWS` arrays from the groups (in place)."""
        self.leader[...] = False
        self.slot[...] = 0
        self.predecessor[...] = -1
        for lo, hi in self.groups:
            self.leader[lo] = True
            self.slot[lo:hi] = np.arange(hi - lo)
            self.predecessor[lo + 1:hi] = np.arange(lo, hi - 1)
        self._pending()

    def update(self, est_xy: np.ndarray, plan_progress: np.ndarray, fixes: dict[int, np.ndarray] | None = None,
               in_view: np.ndarray | None = None) -> list[dict]:
        """Split every group whose leader reached its TP; returns the split events.

        ``fixes`` (robot -> Kinect pose fix of this step) and ``in_view`` (per robot: its estimate lies
        in some Kinect footprint) come from the Kinect system; ``None`` = no Kinects (estimates only).
        A leader with a fix splits when the fix is within ``reach_tol`` of the TP or its plan progress
        is past it; a leader out of view splits on its estimate (odometry); a leader in view but not
        detected this step waits for the next detection.
        """
        events, changed = [], True
        while changed:  # a sub-group may start on its own TP (e.g. several branches at one node)
            changed = False
            for g in list(self.groups):
                tp = self._tps.get(g)
                if tp is None or self.mode == "individual":
                    continue
                lead = g[0]
                past = plan_progress[lead] >= tp.distance - 1e-6
                if fixes is not None and lead in fixes:
                    source, xy = "kinect", np.asarray(fixes[lead][:2], dtype=float)
                elif fixes is None or in_view is None or not in_view[lead]:
                    source, xy = "odometry", est_xy[lead]
                else:
                    continue  # in a footprint, not detected this step: wait for the Kinect
                if not (np.hypot(*(xy - tp.position)) <= self.tol or past):
                    continue
                new = [tuple(b.robots) for b in tp.branches if b.robots[1] > b.robots[0]]
                if new == [g]:
                    del self._tps[g]
                    self._pending()
                    continue
                i = self.groups.index(g)
                self.groups[i:i + 1] = new
                del self._tps[g]
                self.messages["split"] += len(new)
                self.messages["promotion"] += sum(1 for b in new if b[0] != g[0])
                self.splits[source] += 1
                events.append({"tp": tp.node, "position": list(tp.position), "groups": [list(b) for b in new],
                               "source": source})
                changed = True
        if events:
            self._refresh()
        return events

    def count_waypoints(self, advanced: np.ndarray) -> None:
        """A leader whose waypoint advanced asked for (and got) its next desired position."""
        self.messages["waypoint"] += int(np.count_nonzero(advanced & self.leader))

    def count_pose_fixes(self, n: int) -> None:
        self.messages["pose"] += int(n)


def count_waypoints_many(teams: list[Team], advanced: np.ndarray, leader: np.ndarray) -> None:
    """:meth:`Team.count_waypoints` of ``K`` teams: ``advanced`` and the teams' ``leader`` flags ``(K, N)``."""
    for team, n in zip(teams, np.add.reduce(advanced & leader, axis=1, dtype=np.int64).tolist(), strict=True):
        team.messages["waypoint"] += n


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
