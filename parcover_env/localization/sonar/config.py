"""Tunables of the sonar feature localizer (Kim, Pearce & Amato 2001), read from a scenario's
``sonar_localizer`` section: :func:`sonar_localizer_config`.

The env's sonar localization service (``observation.scan``, :mod:`parcover_env.localization.sonar.service`) and
the scripted experts run the localizer; the ``Scenario`` keeps that YAML section as a plain mapping
and this module owns its schema: every field has a unit and is validated with a ``ConfigError``
naming the file and the key.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from parcover_env.config import Scenario, from_mapping
from parcover_env.config.checks import check as _check

__all__ = ["SonarLocalizerConfig", "sonar_localizer_config"]


@dataclass(frozen=True)
class SonarLocalizerConfig:
    """Thresholds of characteristic points, sectors, the Fig. 11 filter and the localizer (SI units).

    Kim, Pearce & Amato's localizer (Fig. 6) is: features of the relaxed sectors meeting the
    uncertainty ellipse x features of the (Fig. 11 filtered) scan -> a pose per pair -> the poses
    near the ellipse -> the one whose synthetic scan matches the measured scan best. Three steps
    here go beyond the paper and are switched on by default (the navigator's missions use them):
    ``polish``, ``arc_fallback`` and ``grid_fallback``. :meth:`paper_method` switches all three off.
    Two choices fill gaps the paper leaves open and stay on in both: the scan error is clipped and
    trimmed (``error_clip``, ``error_trim``), and a caller's heading estimate (odometry) gates the
    candidate poses (``heading_prior_tol_deg``; the paper's uncertainty ellipse is position only).
    """

    jump_threshold: float = 0.3
    """Range difference between neighbouring readings that makes a discontinuity D/c (m)."""
    prominence: float = 0.02
    """A local maximum M / minimum m must differ from the extreme of each side window by this (m)."""
    window: int = 2
    """Half-width (readings) of the window in which M / m must be extreme."""
    far_margin: float = 0.02
    """Readings within this of ``range_max`` are 'f' (too far / no echo) (m)."""
    line_tol: float = 0.03
    """RMS residual under which readings are taken to lie on one wall (m)."""
    plateau_tol: float = 0.03
    """Readings within this of a minimum belong to its plateau (specular cone) (m)."""
    heading_tol_deg: float = 12.0
    """Two wall-derived headings agree when closer than this (deg)."""
    ellipse_distance: float = 0.3
    """Fig. 6 step 7: candidate poses farther than this outside the uncertainty region are dropped (m)."""
    error_clip: float = 0.5
    """Per-reading error cap of the scan comparison (robust to unknown obstacles) (m)."""
    error_trim: float = 0.1
    """Share of the readings with the largest errors left out of the scan comparison (robots near
    the scanning one, multipath paths that a few cm of pose error changes); 0 = all readings."""
    success_error: float = 0.07
    """Localization succeeds when the best pose's mean clipped scan error is below this (m)."""
    polish: bool = True
    """Extension beyond the paper: polish the best pose by a local minimization of the scan error
    (Nelder-Mead, ``polish_iters``). The paper only suggests least squares to cut its 13 cm error
    (§4.1) and does not use it."""
    polish_iters: int = 120
    """Iterations of that polish (Nelder-Mead)."""
    arc_fallback: bool = True
    """Extension beyond the paper: when a (map feature, scan) pair gives no pose near the ellipse
    (neither of the corner's walls shows its perpendicular foot), try poses on the circle of the
    measured corner range around the corner, inside the corner's wedge and the grown ellipse."""
    max_candidates: int = 400
    """Upper bound on synthetic scans per localization."""
    filter: bool = True
    """Run Kim, Pearce & Amato's Fig. 11 filter on the measured scan before feature extraction (too-long
    readings next to the nearest walls are moved onto those walls). The scan comparison uses the
    raw scan, as the synthetic scans model the same sonar."""
    filter_repeats: int = 4
    """Fig. 11 line 1: how many nearest walls are processed ("3 ~ 5 times"; more robots, more)."""
    filter_half_window: int = 1
    """Fig. 11 line 3: readings each side of the nearest one that must lie on a line."""
    filter_line_tol: float = 0.03
    """Fig. 11 line 4: RMS residual under which those readings form a line segment (m)."""
    heading_prior_tol_deg: float = 30.0
    """When the caller passes a heading estimate (odometry), candidate poses whose heading differs
    from it by more than this are dropped (deg)."""
    grid_fallback: bool = True
    """Extension beyond the paper: when no feature-derived pose explains the scan (best error above
    ``success_error``) and a heading estimate is given, scan-match synthetic scans from a grid of
    poses inside the uncertainty ellipse (``grid_step``, ``grid_heading_step_deg``,
    ``grid_heading_steps``)."""
    grid_step: float = 0.05
    """Position step of that grid fallback (m)."""
    grid_heading_step_deg: float = 4.0
    """Heading step of that fallback around the heading estimate (deg)."""
    grid_heading_steps: int = 2
    """Headings tried each side of the estimate by the fallback (0 = the estimate only)."""
    covariance_sigmas: float = 2.0
    """When the uncertainty region is given as a position covariance, its ellipse spans this many
    standard deviations (2 sigma holds ~86 % of a 2-D Gaussian)."""

    def __post_init__(self) -> None:
        for name in ("jump_threshold", "far_margin", "line_tol", "plateau_tol", "heading_tol_deg",
                     "ellipse_distance", "error_clip", "success_error",
                     "filter_line_tol", "covariance_sigmas", "heading_prior_tol_deg", "grid_step"):
            _check(getattr(self, name) > 0, name, f"must be > 0, got {getattr(self, name)}")
        _check(self.prominence >= 0, "prominence", f"must be >= 0, got {self.prominence}")
        _check(0 <= self.error_trim < 1, "error_trim", f"must be in [0, 1), got {self.error_trim}")
        _check(self.grid_heading_steps >= 0, "grid_heading_steps", f"must be >= 0, got {self.grid_heading_steps}")
        _check(self.grid_heading_step_deg > 0, "grid_heading_step_deg",
               f"must be > 0, got {self.grid_heading_step_deg}")
        for name in ("window", "polish_iters", "max_candidates", "filter_repeats", "filter_half_window"):
            _check(getattr(self, name) >= 1, name, f"must be >= 1, got {getattr(self, name)}")
        _check(self.heading_tol_deg < 180, "heading_tol_deg", f"must be < 180, got {self.heading_tol_deg}")

    def paper_method(self) -> SonarLocalizerConfig:
        """This configuration with the extensions beyond the paper off (``polish``, ``arc_fallback``,
        ``grid_fallback``): features + synthetic-scan confirmation + the Fig. 11 filter (as set)."""
        return replace(self, polish=False, arc_fallback=False, grid_fallback=False)


def sonar_localizer_config(scenario: Scenario) -> SonarLocalizerConfig:
    """The ``sonar_localizer`` section of ``scenario`` as a validated :class:`SonarLocalizerConfig`
    (defaults for missing keys); a bad value raises ``ConfigError`` naming the file and the key."""
    return from_mapping(SonarLocalizerConfig, scenario.sonar_localizer, scenario.source, "sonar_localizer")
