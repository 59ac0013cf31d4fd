"""The Kinect system's side of seed A, Alg. 1: formation groups, splits at TPs, promotions, messages.

The team leaves the start as one column (robots ordered as in the plan, so every branch's robots
form a contiguous block ``[lo, hi)``). When a group's leader reaches the TP where that group's
robots part, the system splits it: one sub-group per branch, sized by the robots the branch needs,
the first robot of each block leading it (a promotion for every block but the first). Only
leaders talk to the Kinect system; followers keep formation with their own cameras.

Messages counted by type: ``split`` (to each sub-group at a TP), ``promotion`` (a follower made
leader), ``waypoint`` (next desired position sent to a leader), ``pose`` (a Kinect pose fix sent to
a leader). In ``individual`` mode every robot is its own group: all are localized and messaged.
This is environment infrastructure (what the overhead system does), so RL policies and the
scripted expert observe the same roles; the expert implements the robots' controllers.
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from parcover_env.planning.plan import Plan

__all__ = ["Team"]


class Team:
    def __init__(self, plan: Plan, mode: str = "formation", reach_tol: float = 0.2):
        self.n = plan.r
        self.mode = mode
        self.tol = reach_tol
        self.messages: Counter[str] = Counter()
        self._tps = {tuple(tp.robots): tp for tp in plan.turning_points}
        self.groups: list[tuple[int, int]] = ([(i, i + 1) for i in range(self.n)] if mode == "individual"
                                              else [(0, self.n)])
        self._refresh()

    def _refresh(self) -> None:
        self.leader = np.zeros(self.n, dtype=bool)
        self.slot = np.zeros(self.n, dtype=np.int64)
        self.predecessor = np.full(self.n, -1, dtype=np.int64)
        for lo, hi in self.groups:
            self.leader[lo] = True
            self.slot[lo:hi] = np.arange(hi - lo)
            self.predecessor[lo + 1:hi] = np.arange(lo, hi - 1)

    def update(self, est_xy: np.ndarray, plan_progress: np.ndarray) -> list[dict]:
        """Split every group whose leader reached its TP (within ``reach_tol`` of it, or past it
        along its plan path); returns the split events."""
        events, changed = [], True
        while changed:  # a sub-group may start on its own TP (e.g. several branches at one node)
            changed = False
            for g in list(self.groups):
                tp = self._tps.get(g)
                if tp is None or self.mode == "individual":
                    continue
                near = np.hypot(*(est_xy[g[0]] - tp.position)) <= self.tol
                if not (near or plan_progress[g[0]] >= tp.distance - 1e-6):
                    continue
                new = [tuple(b.robots) for b in tp.branches if b.robots[1] > b.robots[0]]
                if new == [g]:
                    del self._tps[g]
                    continue
                i = self.groups.index(g)
                self.groups[i:i + 1] = new
                del self._tps[g]
                self.messages["split"] += len(new)
                self.messages["promotion"] += sum(1 for b in new if b[0] != g[0])
                events.append({"tp": tp.node, "position": list(tp.position), "groups": [list(b) for b in new]})
                changed = True
        if events:
            self._refresh()
        return events

    def count_waypoints(self, advanced: np.ndarray) -> None:
        """A leader whose waypoint advanced asked for (and got) its next desired position."""
        self.messages["waypoint"] += int(np.count_nonzero(advanced & self.leader))

    def count_pose_fixes(self, n: int) -> None:
        self.messages["pose"] += int(n)
