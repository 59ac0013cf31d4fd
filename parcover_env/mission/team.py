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
(:func:`parcover_env.mission.handover.update_teams`); only those run :meth:`Team.update`.
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from parcover_env.planning.plan import Plan

__all__ = ["Team", "TEAM_ROWS", "count_waypoints_many"]

TEAM_ROWS = ("leader", "slot", "predecessor", "tp_ahead")
"""The :class:`Team` arrays the stepper reads for ``K`` worlds as ``(K, N, ...)`` blocks
(:func:`~parcover_env.sim.rows.score_blocks`). Made once with the team and never rebound:
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
