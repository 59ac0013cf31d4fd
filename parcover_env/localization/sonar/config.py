"""Tunables of the sonar feature localizer (Kim, Pearce & Amato 2001), read from a scenario's
``sonar_localizer`` section: :func:`sonar_localizer_config`.

The env never runs the localizer (the scripted experts do, after a stop-and-scan), so the
``Scenario`` keeps that YAML section as a plain mapping and this module owns its schema: every
field has a unit and is validated with a ``ConfigError`` naming the file and the key.
"""

from __future__ import annotations

from dataclasses import dataclass

from parcover_env.config import Scenario, from_mapping
from parcover_env.config.checks import check as _check

__all__ = ["SonarLocalizerConfig", "sonar_localizer_config"]


@dataclass(frozen=True)
class SonarLocalizerConfig:
    """Thresholds of characteristic points, sectors, the Fig. 11 filter and the localizer (SI units)."""

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
    refine: bool = True
    """Polish the best pose by local minimization of the scan error (the paper's suggested least squares)."""
    refine_iters: int = 120
    """Iterations of that polish (Nelder-Mead)."""
    sector_resolution: float = 0.05
    """Grid cell size for computing visibility sectors (m)."""
    max_candidates: int = 400
    """Upper bound on synthetic scans per localization."""
    filter: bool = True
    """Run seed B's Fig. 11 filter on the measured scan before feature extraction (too-long
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
    grid_step: float = 0.05
    """Fallback when no feature-derived pose explains the scan and a heading estimate is given:
    synthetic scans from poses every this many metres inside the uncertainty ellipse (scan
    matching; not in seed B). 0 = off."""
    grid_heading_step_deg: float = 4.0
    """Heading step of that fallback around the heading estimate (deg)."""
    grid_heading_steps: int = 2
    """Headings tried each side of the estimate by the fallback (0 = the estimate only)."""
    covariance_sigmas: float = 2.0
    """When the uncertainty region is given as a position covariance, its ellipse spans this many
    standard deviations (2 sigma holds ~86 % of a 2-D Gaussian)."""

    def __post_init__(self) -> None:
        for name in ("jump_threshold", "far_margin", "line_tol", "plateau_tol", "heading_tol_deg",
                     "ellipse_distance", "error_clip", "success_error", "sector_resolution",
                     "filter_line_tol", "covariance_sigmas", "heading_prior_tol_deg"):
            _check(getattr(self, name) > 0, name, f"must be > 0, got {getattr(self, name)}")
        _check(self.prominence >= 0, "prominence", f"must be >= 0, got {self.prominence}")
        _check(0 <= self.error_trim < 1, "error_trim", f"must be in [0, 1), got {self.error_trim}")
        _check(self.grid_step >= 0, "grid_step", f"must be >= 0, got {self.grid_step}")
        _check(self.grid_heading_steps >= 0, "grid_heading_steps", f"must be >= 0, got {self.grid_heading_steps}")
        _check(self.grid_heading_step_deg > 0, "grid_heading_step_deg",
               f"must be > 0, got {self.grid_heading_step_deg}")
        for name in ("window", "refine_iters", "max_candidates", "filter_repeats", "filter_half_window"):
            _check(getattr(self, name) >= 1, name, f"must be >= 1, got {getattr(self, name)}")
        _check(self.heading_tol_deg < 180, "heading_tol_deg", f"must be < 180, got {self.heading_tol_deg}")


def sonar_localizer_config(scenario: Scenario) -> SonarLocalizerConfig:
    """The ``sonar_localizer`` section of ``scenario`` as a validated :class:`SonarLocalizerConfig`
    (defaults for missing keys); a bad value raises ``ConfigError`` naming the file and the key."""
    return from_mapping(SonarLocalizerConfig, scenario.sonar_localizer, scenario.source, "sonar_localizer")
