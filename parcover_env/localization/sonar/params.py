"""Tunables of the sonar localizer: now the scenario schema's ``sonar_localizer`` section.

``SonarLocalizerParams`` is kept as the name the localizer modules use; it *is*
:class:`parcover_env.localization.sonar.config.SonarLocalizerConfig`.
"""

from __future__ import annotations

from parcover_env.localization.sonar.config import SonarLocalizerConfig

SonarLocalizerParams = SonarLocalizerConfig

__all__ = ["SonarLocalizerParams"]
