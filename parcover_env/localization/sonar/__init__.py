"""Sonar localization of Kim, Pearce & Amato: characteristic points, visibility sectors, the Fig. 6 localizer."""

from parcover_env.localization.sonar.features import MapFeature, characteristic_points, map_features
from parcover_env.localization.sonar.filter import filter_scan
from parcover_env.localization.sonar.localizer import Ellipse, LocalizationResult, localize
from parcover_env.localization.sonar.params import SonarLocalizerParams
from parcover_env.localization.sonar.sectors import Sector, compute_sectors, sectors_summary

__all__ = ["MapFeature", "characteristic_points", "map_features", "filter_scan", "Ellipse",
           "LocalizationResult", "localize", "SonarLocalizerParams", "Sector", "compute_sectors",
           "sectors_summary"]
