"""Episode metrics, reported in the flat ``info[agent]["metrics/<name>"]`` entries.

Infos are flat (scalars and arrays only, the same keys at reset and at every step: TorchRL's
PettingZoo wrapper builds its spec from the reset infos). ``metrics/*`` entries are 0 (and
``metrics/ended`` is 0) until the step that ends the episode; :func:`episode_metrics` turns an
info back into the metrics dict.

:func:`record_steps` adds one step to the metrics of ``K`` worlds: what the steps accumulate (the
sums and counts of :data:`TOTALS`, the path lengths) are rows of ``(K, ...)`` blocks that one
compiled call updates (:func:`~parcover_env.mission.kernels.record_many`); :func:`record_step` is
its one-world call. Squared errors are summed as ``np.sum`` sums them (numpy's pairwise summation),
the same floats for one world or ``K`` and on every CPU (the formation errors' sums were BLAS dots
before, whose last bits depend on the CPU's BLAS kernel).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from parcover_env.geometry import wrap_angle

__all__ = ["EpisodeMetrics", "formation_errors", "formation_errors_many", "MESSAGE_KINDS", "METRICS_PREFIX",
           "TOTALS", "SUMS", "episode_metrics", "record_step", "record_steps"]

MESSAGE_KINDS = ("split", "promotion", "waypoint", "pose")
"""Kinds of message the Kinect system sends (counted in ``messages``)."""
METRICS_PREFIX = "metrics/"


def formation_errors(poses: np.ndarray, predecessor: np.ndarray, offset: float, l_d: float,
                     psi_d: float) -> tuple[np.ndarray, np.ndarray]:
    """(l - l_d, wrap(psi - psi_d)) of every follower from true poses (Min et al. / Das et al. l-psi)."""
    dl, dpsi, n = formation_errors_many(np.asarray(poses, dtype=float)[None], np.asarray(predecessor)[None], offset,
                                        l_d, psi_d)
    return dl[0, :n[0]], dpsi[0, :n[0]]


def formation_errors_many(poses: np.ndarray, predecessor: np.ndarray, offset: float, l_d: float,
                          psi_d: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`formation_errors` of ``K`` worlds: true poses ``(K, N, 3)``, ``predecessor (K, N)``.
    Returns ``dl, dpsi (K, N)``, world ``k``'s followers in its first ``n[k]`` columns (0 after), and ``n (K,)``."""
    from parcover_env.mission import kernels as step_kernels

    predecessor = np.ascontiguousarray(predecessor, dtype=np.int64)
    dl, dpsi, n = np.empty(predecessor.shape), np.empty(predecessor.shape), np.empty(len(predecessor), dtype=np.int64)
    step_kernels.formation_errors_many(np.ascontiguousarray(poses, dtype=float), predecessor, float(offset),
                                       float(l_d), float(psi_d), dl, dpsi, n)
    return dl, wrap_angle(dpsi), n


TOTALS = ("steps", "time", "kpois_visited", "wall_collisions", "robot_collisions", "sq_err", "n_err", "sq_l", "sq_psi",
          "n_form", "unseen_leader_time", "makespan")
"""The entries of :attr:`EpisodeMetrics.totals`, what a step adds to (counts as floats; ``makespan`` NaN until set)."""
_T = {name: i for i, name in enumerate(TOTALS)}
SUMS = ("totals", "paths")
"""The :class:`EpisodeMetrics` arrays a step adds to."""


class EpisodeMetrics:
    """The metrics of one episode. What the steps accumulate lives in two arrays (:data:`SUMS`), so
    that the metrics of ``K`` worlds can be rows of ``(K, ...)`` blocks (:func:`record_steps`):
    :attr:`totals` (the sums and counts of :data:`TOTALS`) and :attr:`paths`, made here and never
    rebound (the steps add to them in place); the other values are computed from them."""

    def __init__(self, n_kpois: int, n_robots: int, c_max: float, max_speed: float,
                 path_lengths: Sequence[float] | None = None):
        self.n_kpois = n_kpois
        self.n_robots = n_robots
        self.c_max = c_max
        """PPCP lower bound: roadmap shortest-path length to the furthest KPOI (m). Robots drive the
        smoothed routes, which are shorter than roadmap paths, so makespan_ratio can fall below 1."""
        self.max_speed = max_speed
        self.paths = np.zeros(n_robots) if path_lengths is None else np.array(path_lengths, dtype=float)
        """``(N,)`` each robot's path length so far (m): its true straight steps summed (:attr:`path_lengths`)."""
        self.totals = np.zeros(len(TOTALS))
        """The sums and counts of :data:`TOTALS` (``makespan`` NaN while None)."""
        self.totals[_T["makespan"]] = math.nan
        self.team_counts: tuple[Mapping[str, int], Mapping[str, int]] = ({}, {})
        """The team's counters of messages and of splits by source (``Team.messages``, ``Team.splits``),
        linked (not copied) by the first recorded step: :attr:`messages` and the splits read them."""

    def __repr__(self) -> str:
        return f"EpisodeMetrics({self.summary()!r})"

    @property
    def messages(self) -> dict[str, int]:
        """The team's messages by kind, sorted by kind (a zero count kept)."""
        return dict(sorted(self.team_counts[0].items()))

    @messages.setter
    def messages(self, value: Mapping[str, int]) -> None:
        self.team_counts = (dict(value), self.team_counts[1])

    @property
    def kinect_splits(self) -> int:
        """Splits at TPs triggered by the Kinect system detecting the leader there (Min et al. Alg. 1)."""
        return self.team_counts[1].get("kinect", 0)

    @property
    def odometry_splits(self) -> int:
        """Splits decided on the leader's own estimate: its TP lay outside every Kinect footprint."""
        return self.team_counts[1].get("odometry", 0)

    @property
    def path_lengths(self) -> list[float]:
        """Each robot's path length so far (m), a list."""
        return self.paths.tolist()

    @property
    def steps(self) -> int:
        return int(self.totals[_T["steps"]])

    @property
    def time(self) -> float:
        return float(self.totals[_T["time"]])

    @property
    def kpois_visited(self) -> int:
        return int(self.totals[_T["kpois_visited"]])

    @property
    def makespan(self) -> float | None:
        """Time when the last KPOI was visited (s); None if the mission was not completed."""
        t = float(self.totals[_T["makespan"]])
        return None if math.isnan(t) else t

    @makespan.setter
    def makespan(self, value: float | None) -> None:
        self.totals[_T["makespan"]] = math.nan if value is None else value

    @property
    def wall_collisions(self) -> int:
        return int(self.totals[_T["wall_collisions"]])

    @property
    def robot_collisions(self) -> int:
        return int(self.totals[_T["robot_collisions"]])

    @property
    def localization_error(self) -> float:
        """RMS distance between the observed pose estimates and the true poses (m)."""
        t = self.totals
        return math.sqrt(float(t[_T["sq_err"]]) / max(int(t[_T["n_err"]]), 1))

    @property
    def unseen_leader_time(self) -> float:
        """Leader-seconds spent outside every Kinect footprint, driving on odometry (s)."""
        return float(self.totals[_T["unseen_leader_time"]])

    @property
    def formation_error_l(self) -> float:
        """RMS of l - l_d over followers and steps (m)."""
        n = int(self.totals[_T["n_form"]])
        return math.sqrt(float(self.totals[_T["sq_l"]]) / n) if n else 0.0

    @property
    def formation_error_psi(self) -> float:
        """RMS of wrap(psi - psi_d) over followers and steps (rad)."""
        n = int(self.totals[_T["n_form"]])
        return math.sqrt(float(self.totals[_T["sq_psi"]]) / n) if n else 0.0

    def add_formation(self, sq_l: float, sq_psi: float, n_new: int) -> None:
        """Add one step's sums of squared formation errors (m^2, rad^2) over its ``n_new`` followers."""
        t = self.totals
        t[_T["sq_l"]] += sq_l
        t[_T["sq_psi"]] += sq_psi
        t[_T["n_form"]] += n_new

    def record_step(self, time: float, kpois_visited: int, true_poses: np.ndarray,
                    est_poses: np.ndarray, wall: int, robot: int) -> None:
        """Add one step: its time, KPOIs visited, new contacts and the estimates' errors ``(N,)``."""
        err = true_poses[:, :2] - est_poses[:, :2]
        self.add_step(time, kpois_visited, float(np.sum(err * err)), len(err), wall, robot)

    def add_step(self, time: float, kpois_visited: int, sq_err: float, n_err: int, wall: int, robot: int) -> None:
        """Add one step: its time, KPOIs visited, the sum of squared position errors (m^2) of its
        ``n_err`` estimates, and its new wall and robot contacts."""
        t = self.totals
        t[_T["steps"]] += 1
        t[_T["time"]] = time
        t[_T["kpois_visited"]] = kpois_visited
        t[_T["wall_collisions"]] += wall
        t[_T["robot_collisions"]] += robot
        t[_T["sq_err"]] += sq_err
        t[_T["n_err"]] += n_err

    def summary(self) -> dict:
        """Plain-dict summary (JSON-friendly)."""
        out = {"n_kpois": self.n_kpois, "n_robots": self.n_robots, "c_max": self.c_max, "max_speed": self.max_speed,
               "steps": self.steps, "time": self.time, "kpois_visited": self.kpois_visited, "makespan": self.makespan,
               "wall_collisions": self.wall_collisions, "robot_collisions": self.robot_collisions,
               "path_lengths": self.path_lengths, "localization_error": self.localization_error,
               "messages": self.messages, "kinect_splits": self.kinect_splits,
               "odometry_splits": self.odometry_splits, "unseen_leader_time": self.unseen_leader_time,
               "formation_error_l": self.formation_error_l, "formation_error_psi": self.formation_error_psi}
        out["success"] = self.kpois_visited == self.n_kpois
        bound = self.c_max / self.max_speed if self.c_max > 0 else float("nan")
        out["makespan_ratio"] = (self.makespan / bound) if self.makespan is not None else None
        out["collisions"] = self.wall_collisions + self.robot_collisions
        return out

    def flat(self, ended: bool = True) -> dict[str, float | np.ndarray]:
        """The ``metrics/<name>`` info entries: floats (and the ``(N,)`` path lengths). All 0 with
        ``metrics/ended`` = 0 until the episode ends (not NaN: infos must compare equal across
        identical runs); at the end, undefined values (makespan of a failed mission) are NaN."""
        p = METRICS_PREFIX
        if not ended:
            out = dict.fromkeys(_FLAT_KEYS, 0.0)
            out[p + "path_lengths"] = np.zeros(self.n_robots)
            return out
        s = self.summary()
        out = {p + k: math.nan if s[k] is None else float(s[k]) for k in _SCALARS}
        for kind in MESSAGE_KINDS:
            out[f"{p}messages_{kind}"] = float(s["messages"].get(kind, 0))
        out[p + "messages"] = float(sum(s["messages"].values()))
        out[p + "ended"] = 1.0
        out[p + "path_lengths"] = np.asarray(s["path_lengths"], dtype=float)
        return out


_SCALARS = ("n_kpois", "n_robots", "c_max", "max_speed", "steps", "time", "kpois_visited", "makespan",
            "wall_collisions", "robot_collisions", "localization_error", "formation_error_l",
            "formation_error_psi", "success", "makespan_ratio", "collisions", "kinect_splits", "odometry_splits",
            "unseen_leader_time")
_INTS = ("n_kpois", "n_robots", "steps", "kpois_visited", "wall_collisions", "robot_collisions", "collisions",
         "kinect_splits", "odometry_splits")
_FLAT_SCALARS = (*_SCALARS, *(f"messages_{k}" for k in MESSAGE_KINDS), "messages", "ended")
_FLAT_KEYS = tuple(METRICS_PREFIX + k for k in _FLAT_SCALARS)


def episode_metrics(info: dict) -> dict | None:
    """The episode metrics (as :meth:`EpisodeMetrics.summary` gives them) from one agent's flat
    info; None if the info is not from the step that ended the episode."""
    p = METRICS_PREFIX
    if info.get(p + "ended", 0.0) != 1.0:
        return None
    out: dict = {}
    for k in _SCALARS:
        v = float(info[p + k])
        out[k] = None if math.isnan(v) else (int(v) if k in _INTS else v)
    out["success"] = bool(out["success"])
    out["path_lengths"] = np.asarray(info[p + "path_lengths"], dtype=float).tolist()
    out["messages"] = {k: int(info[f"{p}messages_{k}"]) for k in MESSAGE_KINDS}
    return out


def record_step(m: EpisodeMetrics, before: np.ndarray, true: np.ndarray, *, time: float, progress, estimate: np.ndarray,
                new_contacts: tuple[np.ndarray, np.ndarray], team, formation, kinects, control_dt: float) -> None:
    """Add one control step to ``m``: path lengths (true displacement ``before`` -> ``true``), KPOIs
    visited, localization error, new wall / robot contacts (``new_contacts``; a robot-robot contact
    counts for both robots, so halved), formation errors (l-psi, true poses), the team's messages and
    splits (its counters, linked), the time leaders spend outside every Kinect footprint, and the
    makespan once ``progress`` is done (the last KPOI's visit time). The one-world call of :func:`record_steps`."""
    record_steps([m], before[None], true[None], times=[time], progress=[progress], estimates=estimate[None],
                 new_contacts=(new_contacts[0][None], new_contacts[1][None]), teams=[team], formation=formation,
                 kinects=kinects, control_dt=control_dt)


def _rows(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """``(K, N)`` block of ``K`` worlds' ``(N,)`` arrays, to read (a view for ``K = 1``)."""
    return arrays[0][None] if len(arrays) == 1 else np.array(arrays)


def record_steps(metrics: Sequence[EpisodeMetrics], before: np.ndarray, true: np.ndarray, *, times: Sequence[float],
                 progress: Sequence, estimates: np.ndarray, new_contacts: tuple[np.ndarray, np.ndarray],
                 teams: Sequence, formation, kinects, control_dt: float,
                 visits: tuple[np.ndarray, np.ndarray] | None = None,
                 team_rows: Mapping[str, np.ndarray] | None = None,
                 sums: Mapping[str, np.ndarray] | None = None) -> None:
    """:func:`record_step` of ``K`` worlds of one scenario: their metrics, true poses ``before`` and
    ``true`` ``(K, N, 3)``, ``times``, route trackers (``progress``), estimates ``(K, N, 3)``, new
    wall and robot contacts ``(K, N)``, teams; ``kinects`` answers ``in_view`` for every world (the
    footprints are the scenario's) or is None; ``visits``: the trackers' ``visited`` and ``visit_time``
    ``(K, M)`` if at hand (read from the trackers if not); ``team_rows``: the teams' ``leader`` and
    ``predecessor`` ``(K, N)`` by name if at hand (read from the teams if not); ``sums``: the metrics'
    :data:`SUMS` as ``(K, ...)`` blocks whose rows the metrics' arrays are (the score phase's,
    :func:`~parcover_env.sim.score_phase.score_blocks`); if not given, one world's arrays are used as
    they are and several worlds' are gathered and written back. One compiled call adds the step to the
    sums (:func:`~parcover_env.mission.kernels.record_many`); each world's metrics link its team's counters."""
    from parcover_env.mission import kernels as step_kernels

    k_worlds = true.shape[0]
    gathered = sums is None and k_worlds > 1
    if sums is None:
        sums = {name: _rows([getattr(m, name) for m in metrics]) for name in SUMS}
    leader = _rows([t.leader for t in teams]) if team_rows is None else team_rows["leader"]
    predecessor = _rows([t.predecessor for t in teams]) if team_rows is None else team_rows["predecessor"]
    seen = (kinects.in_view(true[leader][:, :2]) if kinects is not None
            else np.zeros(int(np.count_nonzero(leader)), dtype=bool))
    unseen = np.bincount(np.nonzero(leader)[0][~seen], minlength=k_worlds)
    visited, visit_time = visits or (_rows([p.visited for p in progress]), _rows([p.visit_time for p in progress]))
    step = step_kernels.MetricsStep(
        _c(before), _c(true), _c(estimates), _c(predecessor, np.int64),
        _c(visited, bool), _c(visit_time),
        _c(new_contacts[0], np.int64), _c(new_contacts[1], np.int64), _c(unseen, np.int64), _c(times))
    step_kernels.record_many(sums["totals"], sums["paths"], step,
                             (float(formation.offset), float(formation.spacing), math.radians(formation.bearing_deg)),
                             float(control_dt))
    if gathered:
        for k, m in enumerate(metrics):
            m.totals[...], m.paths[...] = sums["totals"][k], sums["paths"][k]
    for m, team in zip(metrics, teams, strict=True):
        counts = m.team_counts
        if counts[0] is not team.messages or counts[1] is not team.splits:  # once per episode
            m.team_counts = (team.messages, team.splits)


def _c(a, dtype=float) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=dtype)
