"""Episode metrics, reported in the flat ``info[agent]["metrics/<name>"]`` entries.

Infos are flat (scalars and arrays only, the same keys at reset and at every step: TorchRL's
PettingZoo wrapper builds its spec from the reset infos). ``metrics/*`` entries are 0 (and
``metrics/ended`` is 0) until the step that ends the episode; :func:`episode_metrics` turns an
info back into the metrics dict.

:func:`record_steps` adds one step to the metrics of ``K`` worlds: the per-robot quantities (path
steps, localization and formation errors, leaders out of the Kinects' view) as ``(K, N)`` arrays in
a few calls, then each world's scalars; :func:`record_step` is its one-world call. The sums keep the
one-world operations (numpy's pairwise summation of the squared errors, the same BLAS dot of each
world's followers), so the metrics are the same floats.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from parcover_env.geometry import wrap_angle

__all__ = ["EpisodeMetrics", "formation_errors", "formation_errors_many", "MESSAGE_KINDS", "METRICS_PREFIX",
           "episode_metrics", "record_step", "record_steps"]

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
    from parcover_env.envs import step_kernels

    predecessor = np.ascontiguousarray(predecessor, dtype=np.int64)
    dl, dpsi, n = np.empty(predecessor.shape), np.empty(predecessor.shape), np.empty(len(predecessor), dtype=np.int64)
    step_kernels.formation_errors_many(np.ascontiguousarray(poses, dtype=float), predecessor, float(offset),
                                       float(l_d), float(psi_d), dl, dpsi, n)
    return dl, wrap_angle(dpsi), n


@dataclass
class EpisodeMetrics:
    n_kpois: int
    n_robots: int
    c_max: float
    """PPCP lower bound: roadmap shortest-path length to the furthest KPOI (m). Robots drive the
    smoothed routes, which are shorter than roadmap paths, so makespan_ratio can fall below 1."""
    max_speed: float
    steps: int = 0
    time: float = 0.0
    kpois_visited: int = 0
    makespan: float | None = None
    """Time when the last KPOI was visited (s); None if the mission was not completed."""
    wall_collisions: int = 0
    robot_collisions: int = 0
    path_lengths: list[float] = field(default_factory=list)
    localization_error: float = 0.0
    """RMS distance between the observed pose estimates and the true poses (m)."""
    messages: dict[str, int] = field(default_factory=dict)
    kinect_splits: int = 0
    """Splits at TPs triggered by the Kinect system detecting the leader there (Min et al. Alg. 1)."""
    odometry_splits: int = 0
    """Splits decided on the leader's own estimate: its TP lay outside every Kinect footprint."""
    unseen_leader_time: float = 0.0
    """Leader-seconds spent outside every Kinect footprint, driving on odometry (s)."""
    formation_error_l: float = 0.0
    """RMS of l - l_d over followers and steps (m)."""
    formation_error_psi: float = 0.0
    """RMS of wrap(psi - psi_d) over followers and steps (rad)."""
    _sq_err: float = 0.0
    _n_err: int = 0
    _sq_form: tuple[float, float, int] = (0.0, 0.0, 0)

    def add_formation(self, sq_l: float, sq_psi: float, n_new: int) -> None:
        """Add one step's sums of squared formation errors (m^2, rad^2) over its ``n_new`` followers."""
        sl, sp, n = self._sq_form
        self._sq_form = sl, sp, n = (sl + sq_l, sp + sq_psi, n + n_new)
        if n:
            self.formation_error_l = math.sqrt(sl / n)
            self.formation_error_psi = math.sqrt(sp / n)

    def record_step(self, time: float, kpois_visited: int, true_poses: np.ndarray,
                    est_poses: np.ndarray, wall: int, robot: int) -> None:
        """Add one step: its time, KPOIs visited, new contacts and the estimates' errors ``(N,)``."""
        err = true_poses[:, :2] - est_poses[:, :2]
        self.add_step(time, kpois_visited, float(np.sum(err * err)), len(err), wall, robot)

    def add_step(self, time: float, kpois_visited: int, sq_err: float, n_err: int, wall: int, robot: int) -> None:
        """Add one step: its time, KPOIs visited, the sum of squared position errors (m^2) of its
        ``n_err`` estimates, and its new wall and robot contacts."""
        self.steps += 1
        self.time = time
        self.kpois_visited = kpois_visited
        self.wall_collisions += wall
        self.robot_collisions += robot
        self._sq_err += sq_err
        self._n_err += n_err
        self.localization_error = math.sqrt(self._sq_err / max(self._n_err, 1))

    def summary(self) -> dict:
        """Plain-dict summary (JSON-friendly)."""
        out = {k: v for k, v in asdict(self).items() if not k.startswith("_")}
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
    splits, the time leaders spend outside every Kinect footprint, and the makespan once ``progress``
    is done (the last KPOI's visit time). The one-world call of :func:`record_steps`."""
    record_steps([m], before[None], true[None], times=[time], progress=[progress], estimates=estimate[None],
                 new_contacts=(new_contacts[0][None], new_contacts[1][None]), teams=[team], formation=formation,
                 kinects=kinects, control_dt=control_dt)


def _rows(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """``(K, N)`` block of ``K`` worlds' ``(N,)`` arrays, to read (a view for ``K = 1``)."""
    return arrays[0][None] if len(arrays) == 1 else np.array(arrays)


def record_steps(metrics: Sequence[EpisodeMetrics], before: np.ndarray, true: np.ndarray, *, times: Sequence[float],
                 progress: Sequence, estimates: np.ndarray, new_contacts: tuple[np.ndarray, np.ndarray],
                 teams: Sequence, formation, kinects, control_dt: float) -> None:
    """:func:`record_step` of ``K`` worlds of one scenario: their metrics, true poses ``before`` and
    ``true`` ``(K, N, 3)``, ``times``, route trackers (``progress``), estimates ``(K, N, 3)``, new
    wall and robot contacts ``(K, N)``, teams; ``kinects`` answers ``in_view`` for every world (the
    footprints are the scenario's) or is None."""
    from parcover_env.envs import step_kernels

    k_worlds, n = true.shape[:2]
    paths, sq_err = np.array([m.path_lengths for m in metrics], dtype=float).reshape(k_worlds, n), np.empty(k_worlds)
    step_kernels.path_and_error_sums(np.ascontiguousarray(before, dtype=float), np.ascontiguousarray(true, dtype=float),
                                     np.ascontiguousarray(estimates, dtype=float), paths, sq_err)
    paths, sq_err = paths.tolist(), sq_err.tolist()
    wall, robot = new_contacts[0].sum(axis=1).tolist(), new_contacts[1].sum(axis=1).tolist()
    predecessor = _rows([t.predecessor for t in teams])
    dl, dpsi, n_followers = formation_errors_many(true, predecessor, formation.offset, formation.spacing,
                                                  math.radians(formation.bearing_deg))
    leader = _rows([t.leader for t in teams])
    seen = (kinects.in_view(true[leader][:, :2]) if kinects is not None
            else np.zeros(int(np.count_nonzero(leader)), dtype=bool))
    unseen = np.bincount(np.nonzero(leader)[0][~seen], minlength=k_worlds).tolist()
    visited = _rows([p.visited for p in progress])
    n_visited, done = np.add.reduce(visited, axis=1, dtype=np.int64).tolist(), visited.all(axis=1).tolist()
    for k, (m, prog, team, f, l_row, psi_row) in enumerate(zip(metrics, progress, teams, n_followers.tolist(), dl,
                                                                dpsi, strict=True)):
        m.path_lengths = paths[k]
        m.add_step(times[k], n_visited[k], sq_err[k], n, wall[k], robot[k] // 2)
        if f:
            l_err, psi_err = l_row[:f], psi_row[:f]
            m.add_formation(float(l_err.dot(l_err)), float(psi_err.dot(psi_err)), f)  # BLAS dots, as one world's
        if m.messages.items() != team.messages.items():  # exact (zero counts too); unchanged most steps
            m.messages = dict(sorted(team.messages.items()))
        m.kinect_splits, m.odometry_splits = team.splits.get("kinect", 0), team.splits.get("odometry", 0)
        if unseen[k]:
            m.unseen_leader_time += control_dt * unseen[k]
        if m.makespan is None and done[k]:
            m.makespan = float(np.nanmax(prog.visit_time))
