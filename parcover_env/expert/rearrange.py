"""Rearranging the subgoals of robots that block each other's scans (Kim, Pearce & Amato §3.2, §4).

When two robots' subgoals lie in the same relaxed sector and one robot stands in the angle range
the other needs to scan the feature eq. 1 selected for it, both share that feature and their
subgoals move to maximize the smaller of their unblocked scan angles (§3.2,
:func:`~parcover_env.localization.sonar.subgoals.best_pair`). The legal space S_i of a robot is its
path's nodes within ``max_shift`` of its subgoal, ahead of it and within its uncertainty horizon,
from where the feature is available ("in general, they can simply move along their paths"), plus
§4's construction: the perpendicular bisector of (their centre, the feature), reached off the path
when the path does not cross it
(:func:`~parcover_env.localization.sonar.subgoals.bisector_rearrangement`). Robots in different
sectors use different features and keep their subgoals (Fig. 10).

The paper rearranges when "one robot is blocking the other robot from scanning a selected
feature" and gives no threshold, no other trigger and no bound on the move. These are OUR
EXTENSIONS, not the paper's:

* the blocking threshold: a loss of at least ``RESOLUTION / 2`` = 0.25 deg of unblocked scan
  angle counts as blocking (:data:`RESOLUTION`, the bearing step of the count);
* the proximity trigger: two subgoals closer than 2 radius + ``separation_margin`` are rearranged
  even when neither blocks the other (``NavigatorConfig.separation_margin``);
* the shift cap: a subgoal moves at most ``max_shift`` = 0.6 m along its path or off it
  (``NavigatorConfig.max_shift``);
* the reaction to bodies that stand still where the plan did not put them (``standing`` in
  :meth:`SubgoalRearranger.rearrange`: a teammate that has finished its route and stands where
  its run left it, an obstacle the map lacks). The paper names such blocking ("the sensor signal
  may be blocked by other robots which appear as moving or unknown obstacles", §1) but rearranges
  pairs of planned subgoals only; a robot whose scan a standing body blocks takes §3.2's two
  ways out alone (the body does not move): the node of its legal space and the feature there
  with the widest unblocked scan angle (:meth:`SubgoalRearranger.react`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from parcover_env.expert.config import NavigatorConfig
from parcover_env.localization.sonar.subgoals import (
    NodeScores,
    PathNodes,
    best_pair,
    bisector_rearrangement,
    unblocked_scan_angle,
)

__all__ = ["Rearranged", "SubgoalRearranger"]

RESOLUTION = math.radians(0.5)
"""Bearing step of the unblocked-angle count (rad); gains below it are no gains. Half of it (0.25 deg)
is the loss of scan angle that counts as blocking: OUR EXTENSION (the paper gives no threshold)."""


@dataclass(frozen=True)
class Rearranged:
    """Targets (arclength labels, ``(N,)``), off-path subgoals (``(N, 2)``, NaN: on the path), the
    number of robot pairs whose subgoals moved, and of pairs whose subgoals lie in different relaxed
    sectors (each robot keeps its own feature: Fig. 10)."""

    targets: np.ndarray
    goals: np.ndarray
    pairs: int
    apart: int = 0
    close: int = 0
    """Of ``pairs``, those the proximity trigger fired (subgoals closer than 2 radius +
    ``separation_margin``; our extension), whether or not one also blocked the other."""
    reacted: tuple[int, ...] = ()
    """Robots whose subgoals moved because a ``standing`` body blocked their scan (our extension)."""


class SubgoalRearranger:
    """The known map's sectors and free space, the robots' size and sonar: rearranges a team's subgoals."""

    def __init__(self, features, sectors, map_model, radius: float, range_max: float, incidence: float,
                 cone: float, params: NavigatorConfig):
        self.features, self.sectors, self.p = features, sectors, params
        self.args = (radius, range_max, incidence, cone)
        self.min_sep = 2 * radius + params.separation_margin
        self.region = map_model.free.buffer(-(radius + params.stop_margin))
        shapely.prepare(self.region)

    def free(self, points) -> np.ndarray:
        """Whether each point ``(K, 2)`` is where a robot may stand off its path (free space eroded
        by radius + ``stop_margin``)."""
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        return shapely.contains_xy(self.region, pts[:, 0], pts[:, 1])

    def sector_of(self, xy) -> int:
        """Index of the first relaxed sector whose region covers ``xy``; -1 if none does."""
        p = shapely.Point(*np.asarray(xy, dtype=float))
        return next((k for k, s in enumerate(self.sectors) if s.polygon.distance(p) <= 1e-9), -1)

    def rearrange(self, paths: list[PathNodes], scores: list[NodeScores], targets: np.ndarray,
                  windows: np.ndarray, active: np.ndarray, standing=None) -> Rearranged:
        """Subgoals after rearranging each blocked pair once; ``windows (N, 2)`` the labels a robot's
        subgoal may take (ahead of it, within its horizon). ``standing (M, 2)``: bodies of the robots'
        size that will stand still during the scans where the run put them, not in ``active`` (e.g.
        teammates done with their routes, at their believed positions); an active robot not moved
        with a teammate whose scan one of them blocks moves alone (:meth:`react`, our extension)."""
        n = len(paths)
        out, goals = np.asarray(targets, dtype=float).copy(), np.full((n, 2), np.nan)
        moved, pairs, n_close = np.zeros(n, dtype=bool), 0, 0
        idx = [paths[i].index(out[i]) for i in range(n)]
        pts = np.array([paths[i].xy[k] for i, k in enumerate(idx)])
        sector = [self.sector_of(p) for p in pts]
        blocked = []  # (loss of scan angle, i, j, feature of i): robot j blocks robot i
        for i in active:
            fi = int(scores[i].feature[idx[i]])  # the feature eq. 1 selected at the subgoal
            if fi < 0:
                continue
            alone = unblocked_scan_angle(pts[i], self.features[fi], np.zeros((0, 2)), *self.args)
            for j in active:
                if j == i or sector[i] != sector[j] or sector[i] < 0:
                    continue
                loss = alone - unblocked_scan_angle(pts[i], self.features[fi], pts[[j]], *self.args)
                close = bool(np.hypot(*(pts[i] - pts[j])) < self.min_sep)
                if loss >= RESOLUTION / 2 or close:  # threshold and proximity trigger: our extensions
                    blocked.append((loss + (math.inf if close else 0.0), int(i), int(j), fi, close))
        for _, i, j, fi, close in sorted(blocked, reverse=True):  # the most blocked robot first
            if moved[i] or moved[j]:
                continue
            new = self._pair((i, j), paths, scores, out, windows, fi, close)
            if new is not None:
                (out[i], out[j]), goals[[i, j]] = new
                moved[[i, j]], pairs, n_close = True, pairs + 1, n_close + int(close)
        apart = sum(sector[i] != sector[j] for a, i in enumerate(active) for j in active[a + 1:])
        reacted = []
        bodies = np.zeros((0, 2)) if standing is None else np.asarray(standing, dtype=float).reshape(-1, 2)
        if len(bodies):
            for i in active:
                if moved[i]:
                    continue
                mates = [k for k in active if k != i]
                at = np.array([goals[k] if np.isfinite(goals[k, 0]) else paths[k].point(out[k]) for k in mates])
                new = self.react(paths[i], scores[i], out[i], windows[i], np.vstack([bodies, at.reshape(-1, 2)]),
                                 n_fixed=len(bodies))
                if new is not None:
                    out[i], moved[i] = new, True
                    reacted.append(int(i))
        return Rearranged(out, goals, pairs, int(apart), n_close, tuple(reacted))

    def react(self, path: PathNodes, scores: NodeScores, target: float, window, others, n_fixed: int | None = None):
        """The label a robot's subgoal moves to because ``others[:n_fixed]`` (bodies standing still
        where the run put them; default all of ``others (M, 2)``) block its scan of the feature eq. 1
        chose at ``target``, or None: not blocked by them (a loss below 0.25 deg) or no better node.
        §3.2's two ways out, for one robot (a standing body does not move): scan a different feature,
        or move along the path. The candidates are the nodes of its legal space (its path within
        ``window`` and ``max_shift``, at least 2 radius + ``separation_margin`` from every one of
        ``others``) with each feature available there; the best has the widest scan angle unblocked
        by all of ``others``, ties within ``RESOLUTION`` going to the smallest move. The subgoal
        moves if that beats the chosen feature at ``target`` by ``RESOLUTION`` and is not at
        ``target`` itself (there the robot scans the other feature). Our extension (module docstring)."""
        oth = np.asarray(others, dtype=float).reshape(-1, 2)
        fixed = oth[: len(oth) if n_fixed is None else n_fixed]
        k0 = path.index(target)
        fi = int(scores.feature[k0])
        if fi < 0 or len(fixed) == 0:
            return None
        f, p0 = self.features[fi], path.xy[k0]
        alone = unblocked_scan_angle(p0, f, np.zeros((0, 2)), *self.args)
        if alone - unblocked_scan_angle(p0, f, fixed, *self.args) < RESOLUTION / 2:
            return None
        before = unblocked_scan_angle(p0, f, oth, *self.args)
        lo = max(window[0], target - self.p.max_shift) - 1e-9
        hi = min(window[1], target + self.p.max_shift) + 1e-9
        cand = np.nonzero((path.s >= lo) & (path.s <= hi) & scores.available.any(axis=1))[0]
        gap = np.hypot(path.xy[cand, None, 0] - oth[None, :, 0], path.xy[cand, None, 1] - oth[None, :, 1])
        cand = cand[np.all(gap >= self.min_sep, axis=1)]
        if len(cand) == 0:
            return None
        value = np.array([max(unblocked_scan_angle(path.xy[k], self.features[g], oth, *self.args)
                              for g in np.flatnonzero(scores.available[k])) for k in cand])
        top = float(value.max())
        if top < before + RESOLUTION:
            return None
        near = cand[value >= top - RESOLUTION / 2]
        best = near[np.argmin(np.abs(path.s[near] - target))]
        return None if best == k0 else float(path.s[best])

    def _worst(self, pts: np.ndarray, f) -> float:
        return min(unblocked_scan_angle(pts[a], f, pts[[1 - a]], *self.args) for a in range(2))

    def _pair(self, pair, paths, scores, targets, windows, fi: int, close: bool):
        """New labels and off-path goals ``((t_i, t_j), (2, 2))`` of ``pair``, or None (no gain)."""
        f = self.features[fi]
        pts = np.array([paths[k].point(targets[k]) for k in pair])
        before = self._worst(pts, f)
        cands = []
        for k in pair:
            p, lo, hi = paths[k], *windows[k]
            lo, hi = max(lo, targets[k] - self.p.max_shift) - 1e-9, min(hi, targets[k] + self.p.max_shift) + 1e-9
            near = (p.s >= lo) & (p.s <= hi)
            cands.append(np.nonzero(near & scores[k].available[:, fi])[0])
        a, b = (paths[k] for k in pair)
        ca, cb = cands
        cost = np.abs(a.s[ca] - targets[pair[0]])[:, None] + np.abs(b.s[cb] - targets[pair[1]])[None, :]
        best = best_pair(a.xy[ca], b.xy[cb], f, self.min_sep, *self.args, cost=cost, resolution=RESOLUTION)
        choice = None
        if best.a >= 0:
            choice = ((float(a.s[ca[best.a]]), float(b.s[cb[best.b]])), np.full((2, 2), np.nan), best.value)
        off = self._bisector(pair, paths, targets, windows, f, pts)
        if off is not None and (choice is None or off[2] > choice[2] + RESOLUTION):
            choice = off
        if choice is None or choice[2] < before + (-1e-9 if close else RESOLUTION):
            return None
        return choice[0], choice[1]

    def _bisector(self, pair, paths, targets, windows, f, pts):
        """§4's bisector subgoals as ``(labels, off-path goals, min unblocked angle)``, or None."""
        wins = [tuple(windows[k]) for k in pair]
        res = bisector_rearrangement(pts, [paths[k] for k in pair], targets[list(pair)], f.point, self.min_sep,
                                     free=self.free, max_slide=self.p.max_shift, slide_step=self.p.shift_step,
                                     windows=wins)
        sub = res.subgoals
        if np.hypot(*(sub[0] - sub[1])) < self.min_sep - 1e-9:
            return None
        labels, goals = [], np.full((2, 2), np.nan)
        for a, k in enumerate(pair):
            p = paths[k]
            win = np.nonzero((p.s >= wins[a][0]) & (p.s <= wins[a][1]))[0]
            if len(win) == 0:
                return None
            d = np.hypot(*(p.xy[win] - sub[a]).T)
            node = win[int(np.argmin(d))]
            labels.append(float(p.s[node]))
            if res.on_path[a] and d.min() <= self.p.node_step:
                continue
            # off the path: reachable straight from the nearest path node of the window
            if d.min() > self.p.max_shift or not self.region.covers(shapely.LineString([p.xy[node], sub[a]])):
                return None
            goals[a] = sub[a]
        return tuple(labels), goals, self._worst(sub, f)
