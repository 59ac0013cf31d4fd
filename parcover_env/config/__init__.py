"""Configuration: the typed scenario schema and the YAML reading that fills it.

Loading a scenario *by name* (and checking it against the map's geometry) is
:func:`parcover_env.scenarios.load_scenario`.
"""

from parcover_env.config.loading import deep_merge, read_yaml, replace_source, scenario_from_mapping, scenario_to_yaml
from parcover_env.config.schema import (
    DriveConfig,
    EpisodeConfig,
    FormationConfig,
    KinectConfig,
    KinectTrackingConfig,
    MapConfig,
    ObservationConfig,
    OdometryConfig,
    PhysicsConfig,
    PlannerConfig,
    Point,
    Polygon,
    Pose,
    RewardConfig,
    RobotConfig,
    ScanConfig,
    Scenario,
    Segment,
    SonarConfig,
)
from parcover_env.config.typed import from_mapping, to_mapping
from parcover_env.errors import ConfigError

__all__ = [
    "ConfigError", "MapConfig", "Pose", "SonarConfig", "DriveConfig", "OdometryConfig", "RobotConfig", "KinectConfig",
    "PhysicsConfig", "EpisodeConfig", "RewardConfig", "ObservationConfig", "FormationConfig", "PlannerConfig",
    "KinectTrackingConfig", "ScanConfig",
    "Scenario", "Point", "Polygon", "Segment", "read_yaml", "deep_merge", "scenario_from_mapping",
    "scenario_to_yaml", "replace_source", "from_mapping", "to_mapping",
]
