"""Parameters of the seed B sonar navigator (see :mod:`parcover_env.expert.navigator`)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["NavigatorParams"]


@dataclass(frozen=True)
class NavigatorParams:
    """Tunables of the navigator (SI units)."""

    node_step: float = 0.05
    """Spacing of the path nodes scored as subgoal candidates (m)."""
    initial_axis: float = 0.05
    """Ellipse semi-axes at the start and after a fix (m)."""
    rate_distance: float = 0.05
    """Ellipse growth per metre travelled (m/m)."""
    rate_rotation: float = 0.03
    """Ellipse growth per radian turned (m/rad)."""
    max_axis: float = 0.35
    """The subgoal is chosen before the ellipse semi-axis exceeds this (m)."""
    min_advance: float = 0.6
    """A new team subgoal is at least this far along the route (m)."""
    tie_tol_deg: float = 5.0
    """Biases within this of the best count as equal; then the farthest node wins (deg)."""
    min_wall_length: float = 0.3
    min_readings: int = 2
    min_walls_seen: int = 1
    range_margin: float = 0.15
    max_shift: float = 0.6
    """Rearrangement: how far a subgoal may move along its path (m)."""
    shift_step: float = 0.1
    separation_margin: float = 0.15
    """Robots at their subgoals stay at least 2 radius + this apart (m)."""
    lookahead: float = 0.35
    arrive_tol: float = 0.05
    goal_tol: float = 0.1
    """A robot is done when a successful fix puts it within this of its route's end (m)."""
    max_final_scans: int = 3
    scan_rate: float = 0.5
    """Turn rate while scanning (rad/s); keep rate * dt below the 5 deg bin."""
    bin_tol_deg: float = 2.0
    drive_timeout: float = 20.0
    """Extra seconds over the nominal driving time before a drive phase is cut short."""
    stop_margin: float = 0.05
    slow_margin: float = 0.25
    sector_rule: int = 2
    teammates_in_map: bool = True
    """Localize against the known map plus the teammates' discs at their believed positions."""
    accept_error: float = 0.07
    """A fix is accepted when the mean clipped error between the scan and the synthetic scan of the known
    map *with the other robots' discs at their beliefs* is below this (m). The localizer's own
    success test sees teammates as unknown obstacles and rejects good poses next to them."""

    def __post_init__(self) -> None:
        for name in ("node_step", "rate_distance", "max_axis", "min_advance", "lookahead", "arrive_tol",
                     "goal_tol", "scan_rate", "bin_tol_deg", "shift_step"):
            if not getattr(self, name) > 0:
                raise ValueError(f"NavigatorParams.{name} must be > 0, got {getattr(self, name)}")
        if self.sector_rule not in (0, 1, 2):
            raise ValueError(f"NavigatorParams.sector_rule must be 0, 1 or 2, got {self.sector_rule}")
