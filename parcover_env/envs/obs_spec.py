"""The observation spec: every entry of an agent's observation, declared once.

Each :class:`Entry` gives its name, size, unit, bounds (functions of the scenario and the map's
box), source, meaning and the presets it appears in. Everything else is generated from
:data:`ENTRIES`: the layout and its slices (:class:`~parcover_env.envs.observations.ObservationLayout`),
the ``observation_space`` bounds, the observation table of ``ParallelCoverageEnv``'s docstring
(:func:`markdown_table`) and the columns of the compiled pass that writes the non-sensor entries
(:data:`KERNEL_COLUMNS`: one named field per entry, so the kernel addresses a column by its name).

Sources: ``estimate``, ``team``, ``mission`` and ``camera`` entries are written by that compiled pass
from the env's state; ``route`` and ``teammates`` entries (observation version 2 only) by
:func:`parcover_env.envs.obs_v2.fill` for all robots of all worlds at once; ``scan`` entries by the
stepper from ``env.localization_entries()`` (the sonar localization service,
:mod:`parcover_env.localization.sonar.service`); a ``sensor`` entry is the reading of the sensor its ``sensor``
factory builds from the scenario (a :class:`~parcover_env.sensors.base.Sensor`), filled for every world
at once by the stepper (:mod:`parcover_env.sim.pipeline`). A new sensor is a sensor module, a config
field and one ``sensor`` entry here: neither the env nor the batched worlds change.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from parcover_env.config import Scenario
from parcover_env.sensors.base import Sensor
from parcover_env.sensors.lidar import Lidar
from parcover_env.sensors.sonar import SonarRing

__all__ = ["Entry", "ENTRIES", "KERNEL_ENTRIES", "KERNEL_COLUMNS", "V2_ENTRIES", "MAX_FIX_AGE", "MAX_ROBOTS",
           "N_PREVIEW", "VERSION_SOURCES", "markdown_table"]

VERSION_SOURCES: dict[int, tuple[str, ...]] = {
    1: ("estimate", "team", "mission", "camera", "scan", "sensor"),
    2: ("estimate", "team", "mission", "camera", "scan", "sensor", "route", "teammates"),
}
"""The entry sources each observation version's observation holds (the ``sources`` of its feature set,
:mod:`parcover_env.envs.feature_sets`; kept here, below the feature sets, which read the spec)."""

MAX_FIX_AGE = 60.0
"""Seconds since the last absolute pose fix are reported capped at this value."""
MAX_ROBOTS = 16
"""Most robots a version-2 env takes (``state()`` is padded to it; robot counts are bounded by it)."""
N_PREVIEW = 3
"""Version 2: route vertices ahead in the route preview (``wp_dx``, ``wp_dy``)."""
KERNEL_SOURCES = ("estimate", "team", "mission", "camera")

Box = tuple[float, float, float, float]
"""The map's bounds ``(x0, y0, x1, y1)`` (m)."""
BOTH = ("realistic", "ideal")
MARGIN = 1.0
"""Estimates may drift off the floor a little: x, y are bounded by the map box +- this (m)."""


def _diag(box: Box) -> float:
    return float(np.hypot(box[2] - box[0], box[3] - box[1]))


def _unit(s: Scenario, box: Box) -> tuple[float, float]:
    return -1.0, 1.0


def _flag(s: Scenario, box: Box) -> tuple[float, float]:
    return 0.0, 1.0


def _goal(s: Scenario, box: Box) -> tuple[float, float]:
    return -_diag(box) - 2 * MARGIN, _diag(box) + 2 * MARGIN


def _pred(s: Scenario, box: Box) -> tuple[float, float]:
    return -s.formation.camera_range, s.formation.camera_range


def _ellipse_axis(s: Scenario, box: Box) -> tuple[float, float]:
    return 0.0, _diag(box)


def _covariance(s: Scenario) -> int:
    return int(s.observation.pose_covariance)


def _dist(s: Scenario, box: Box) -> tuple[float, float]:
    return 0.0, _diag(box) + 2 * MARGIN


def _count(s: Scenario, box: Box) -> tuple[float, float]:
    return 0.0, float(MAX_ROBOTS)


def _speed2(s: Scenario, box: Box) -> tuple[float, float]:
    return -2.0 * s.robot.max_speed, 2.0 * s.robot.max_speed


def _k(s: Scenario) -> int:
    return s.observation.neighbours


def _preview(s: Scenario) -> int:
    return N_PREVIEW


def _scan(s: Scenario) -> int:
    return int(s.observation.scan.enabled)


@dataclass(frozen=True)
class Entry:
    """One named entry of the observation vector."""

    name: str
    unit: str
    meaning: str
    bounds: Callable[[Scenario, Box], tuple[float, float]]
    """``(low, high)`` of every column of the entry, from the scenario and the map's box."""
    source: str
    """``estimate`` / ``team`` / ``mission`` / ``camera`` (the compiled pass), ``sensor``, or ``scan``
    (the env's sonar localization service, ``env.localization_entries()``)."""
    size: Callable[[Scenario], int] | None = None
    """Columns in this scenario (0 = absent); None = 1 column (or the sensor's ``size``)."""
    sensor: Callable[[Scenario], Sensor | None] | None = None
    """``sensor`` entries: builds the sensor from the scenario, None when it is switched off."""
    presets: tuple[str, ...] = BOTH
    """Presets in which the entry is on by default."""
    size_doc: str = "1"
    """The size as the docstring table shows it."""
    bounds_doc: str = ""
    """The bounds as the docstring table shows them (default: those of the shared helpers)."""

    def bounds_text(self) -> str:
        named = {_unit: "[-1, 1]", _flag: "[0, 1]", _goal: "+-(map diagonal + 2)", _pred: "+-camera_range",
                 _ellipse_axis: "[0, map diagonal]", _dist: "[0, map diagonal + 2]",
                 _count: f"[0, {MAX_ROBOTS}]", _speed2: "+-2 max_speed"}
        return self.bounds_doc or named[self.bounds]

    @property
    def versions(self) -> tuple[int, ...]:
        """The observation versions whose feature set holds the entry's source
        (:data:`VERSION_SOURCES`, which :data:`~parcover_env.envs.feature_sets.FEATURE_SETS` own)."""
        return tuple(v for v, sources in VERSION_SOURCES.items() if self.source in sources)

    def n_columns(self, s: Scenario, sensor: Sensor | None = None, sources: tuple[str, ...] | None = None) -> int:
        """Columns of the entry in scenario ``s`` (0: absent): ``sensor`` its built sensor, ``sources`` the
        entry sources of the scenario's feature set (looked up from ``observation.version`` if not given)."""
        if sources is None:
            sources = VERSION_SOURCES[s.observation.version]
        if self.source not in sources:
            return 0
        if self.source == "sensor":
            return sensor.size if sensor is not None else 0
        return 1 if self.size is None else self.size(s)


ENTRIES: tuple[Entry, ...] = (
    Entry("x", "m", "pose estimate x: odometry, reset by Kinect fixes of seen leaders (``pose_source``)",
          lambda s, b: (b[0] - MARGIN, b[2] + MARGIN), "estimate",
          bounds_doc="map x +- 1"),
    Entry("y", "m", "pose estimate y", lambda s, b: (b[1] - MARGIN, b[3] + MARGIN), "estimate",
          bounds_doc="map y +- 1"),
    Entry("cos_theta", "-", "cosine of the heading estimate", _unit, "estimate"),
    Entry("sin_theta", "-", "sine of the heading estimate", _unit, "estimate"),
    Entry("v", "m/s", "encoder speed: odometry increment of the last step / step (ideal: command)",
          lambda s, b: (-s.robot.max_speed, s.robot.max_speed), "estimate", bounds_doc="+-max_speed"),
    Entry("omega", "rad/s", "encoder turn rate, as ``v``",
          lambda s, b: (-s.robot.max_turn_rate, s.robot.max_turn_rate), "estimate", bounds_doc="+-max_turn_rate"),
    Entry("leader", "-", "1 if the robot leads its group, else 0 (follower)", _flag, "team"),
    Entry("slot", "-", "position in its group's column / (n_robots - 1); 0 = leader", _flag, "team"),
    Entry("fix_age", "s", f"time since the last absolute pose fix, capped at {MAX_FIX_AGE:g} s (large = stale)",
          lambda s, b: (0.0, MAX_FIX_AGE), "estimate", bounds_doc=f"[0, {MAX_FIX_AGE:g}]"),
    Entry("sigma_major", "m", "major axis (1 sigma) of the position uncertainty ellipse of the estimate",
          _ellipse_axis, "estimate", _covariance, presets=("realistic",)),
    Entry("sigma_minor", "m", "minor axis (1 sigma) of that ellipse", _ellipse_axis, "estimate",
          _covariance, presets=("realistic",)),
    Entry("sigma_axis_cos2", "-", "cos of twice the major axis angle, robot frame (1 if round)", _unit, "estimate",
          _covariance, presets=("realistic",)),
    Entry("sigma_axis_sin2", "-", "sin of twice the major axis angle, robot frame (0 if round)", _unit, "estimate",
          _covariance, presets=("realistic",)),
    Entry("sigma_heading", "rad", "heading sigma of the estimate", lambda s, b: (0.0, np.pi), "estimate",
          _covariance, presets=("realistic",), bounds_doc="[0, pi]"),
    Entry("scanning", "-", "1 while this robot's sonar scan is under way (held still; ``observation.scan``)",
          _flag, "scan", _scan, presets=(), size_doc="1 (opt-in)"),
    Entry("scan_result", "-", "outcome of this robot's last scan: 1 fix accepted; 0.5 fix held until a scan from "
          "elsewhere agrees (``confirm_widened``); -0.5 uninformative (matched, but nothing pins the pose down "
          "here: scan elsewhere); -1 rejected (no match in the region: the next one is wider); 0 no scan yet",
          _unit, "scan", _scan, presets=(), size_doc="1 (opt-in)"),
    Entry("goal_dx", "m", "current route waypoint in the robot frame, x ahead (from the estimate)", _goal, "mission"),
    Entry("goal_dy", "m", "current route waypoint in the robot frame, y left", _goal, "mission"),
    Entry("pred_dx", "m", "robot ahead in the column, x in this robot's frame (onboard camera; 0 if unseen)",
          _pred, "camera"),
    Entry("pred_dy", "m", "robot ahead in the column, y in this robot's frame", _pred, "camera"),
    Entry("pred_cos", "-", "cos of its heading relative to this robot's (0 if unseen)", _unit, "camera"),
    Entry("pred_sin", "-", "sin of its heading relative to this robot's (0 if unseen)", _unit, "camera"),
    Entry("pred_visible", "-", "1 if a follower's camera sees its predecessor (FOV, range, walls)", _flag, "camera"),
    Entry("kpois_visited", "-", "fraction of KPOIs visited by the team", _flag, "mission"),
    Entry("time", "-", "fraction of the step limit elapsed", _flag, "mission"),
    # version 2's feature set: what a robot needs to drive, wait, follow or split (filled by envs/obs_v2.py)
    Entry("own_kpoi_cos", "-", "bearing (cos, robot frame, from the estimate) of its target KPOI: the next "
          "KPOI of its own route not yet visited (the last one once all are): where to drive", _unit, "route"),
    Entry("own_kpoi_sin", "-", "bearing (sin) of its target KPOI", _unit, "route"),
    Entry("own_kpoi_dist", "m", "straight distance from the estimate to its target KPOI: how far its own work is",
          _dist, "route"),
    Entry("done_mask", "-", "1 once every KPOI of its own route is visited (by anyone; also its target KPOI's "
          "visited flag): its work is done, mask it (death masking)", _flag, "route"),
    Entry("wp_dx", "m", f"route preview: its next {N_PREVIEW} route vertices (the last repeated at the end), x "
          "ahead in the robot frame, from the estimate: the road beyond the lookahead goal", _goal, "route", _preview,
          size_doc=str(N_PREVIEW)),
    Entry("wp_dy", "m", "route preview, y left", _goal, "route", _preview, size_doc=str(N_PREVIEW)),
    Entry("tp_ahead", "-", "1 if a turning point (TP) of its route lies ahead (plan progress before it): a split "
          "is coming", _flag, "route"),
    Entry("tp_dx", "m", "the next TP, x ahead in the robot frame (0 if none ahead): where its group splits", _goal,
          "route"),
    Entry("tp_dy", "m", "the next TP, y left (0 if none ahead)", _goal, "route"),
    Entry("tp_group", "robots", "robots arriving together at the next TP (0 if none ahead)", _count, "route"),
    Entry("tp_branches", "-", "branches leaving the next TP with robots on them (0 if none ahead)", _count, "route"),
    Entry("tp_own_branch", "robots", "robots taking its own branch at the next TP, itself included (0 if none "
          "ahead): whether it leads, follows or goes alone after the split", _count, "route"),
    Entry("group_size", "robots", "robots in its formation group now, itself included: whom it travels with",
          _count, "teammates"),
    Entry("mate_dx", "m", "k nearest teammates (by estimated distance, nearest first; ``observation.neighbours`` "
          "= k): x ahead in the robot frame, from the shared estimates (0 in padding): whom to follow or avoid",
          _goal, "teammates", _k, size_doc="k"),
    Entry("mate_dy", "m", "those teammates, y left (0 in padding)", _goal, "teammates", _k,
          size_doc="k"),
    Entry("mate_cos", "-", "cos of each one's heading relative to this robot's (0 in padding)", _unit, "teammates",
          _k, size_doc="k"),
    Entry("mate_sin", "-", "sin of that relative heading (0 in padding)", _unit, "teammates", _k,
          size_doc="k"),
    Entry("mate_dvx", "m/s", "its encoder velocity minus this robot's, x in the robot frame (0 in padding): closing "
          "in or falling back", _speed2, "teammates", _k, size_doc="k"),
    Entry("mate_dvy", "m/s", "relative velocity, y in the robot frame (0 in padding)", _speed2, "teammates", _k,
          size_doc="k"),
    Entry("mate_leader", "-", "1 if that teammate leads its group (0 in padding)", _flag, "teammates", _k,
          size_doc="k"),
    Entry("mate_mask", "-", "1 for a real teammate, 0 for padding (fewer than k teammates)", _flag, "teammates", _k,
          size_doc="k"),
    Entry("sonar", "m", "sonar ring ranges, one per beam (``robot.sonar``); max range = no echo",
          lambda s, b: (0.0, s.robot.sonar.range_max), "sensor", bounds_doc="[0, range_max]",
          sensor=lambda s: SonarRing(s.robot.sonar) if s.observation.sonar else None, size_doc="B (beams)"),
    Entry("lidar", "m", "2-D lidar ranges, ray i at 360 i / n_rays deg from the heading (``robot.lidar``); "
          "range_max = no hit", lambda s, b: (0.0, s.robot.lidar.range_max), "sensor", bounds_doc="[0, range_max]",
          sensor=lambda s: Lidar(s.robot.lidar) if s.robot.lidar.enabled else None, presets=(), size_doc="R (rays)"),
)
"""The observation, in column order."""

KERNEL_ENTRIES = tuple(e.name for e in ENTRIES if e.source in KERNEL_SOURCES)
"""The entries the compiled pass writes (all but the sensors' and version 2's ``route`` / ``teammates``)."""

V2_ENTRIES = tuple(e.name for e in ENTRIES if e.source in ("route", "teammates"))
"""The entries :func:`parcover_env.envs.obs_v2.fill` writes (observation version 2)."""

KERNEL_COLUMNS = np.dtype([(name, "i8") for name in KERNEL_ENTRIES])
"""Record of the column of each :data:`KERNEL_ENTRIES` entry in a layout (-1: absent), addressed by
name in the compiled pass (``parcover_env.envs.observations.scalar_entries``). A structured array,
not a NamedTuple: numba types it in its C dispatcher (a NamedTuple is typed field by field)."""


def markdown_table() -> str:
    """The observation table of ``ParallelCoverageEnv``'s docstring, generated from :data:`ENTRIES`."""
    rows = ["| entry | size | unit | bounds | source | presets | versions | meaning |",
            "|---|---|---|---|---|---|---|---|"]
    for e in ENTRIES:
        presets = ", ".join(e.presets) if e.presets else "off (opt-in)"
        versions = ", ".join(f"v{v}" for v in e.versions)
        cells = (e.name, e.size_doc, e.unit, e.bounds_text(), e.source, presets, versions, e.meaning)
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows)
