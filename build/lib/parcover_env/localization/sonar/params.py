"""Tunable thresholds of the sonar localizer (not yet part of the scenario config)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SonarLocalizerParams"]


@dataclass(frozen=True)
class SonarLocalizerParams:
    """Thresholds of characteristic points, sectors and the localizer (SI units)."""

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
    """Fig. 6 step 7: candidate poses farther than this outside the ellipse are dropped (m)."""
    error_clip: float = 0.5
    """Per-reading error cap of the scan comparison (robust to unknown obstacles) (m)."""
    success_error: float = 0.07
    """Localization succeeds when the best pose's mean clipped scan error is below this (m)."""
    refine: bool = True
    """Polish the best pose by local minimization of the scan error (the paper's suggested least squares)."""
    refine_iters: int = 120
    sector_resolution: float = 0.05
    """Grid cell size for computing visibility sectors (m)."""
    max_candidates: int = 400
    """Upper bound on synthetic scans per localization."""

    def __post_init__(self) -> None:
        for name in ("jump_threshold", "far_margin", "line_tol", "plateau_tol", "heading_tol_deg",
                     "ellipse_distance", "error_clip", "success_error", "sector_resolution"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SonarLocalizerParams.{name} must be > 0, got {getattr(self, name)}")
        if self.prominence < 0:
            raise ValueError(f"SonarLocalizerParams.prominence must be >= 0, got {self.prominence}")
        for name in ("window", "refine_iters", "max_candidates"):
            if getattr(self, name) < 1:
                raise ValueError(f"SonarLocalizerParams.{name} must be >= 1, got {getattr(self, name)}")
