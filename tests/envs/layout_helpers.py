"""A layout from plain numbers (box, speeds, sonar, camera range), through the spec and a scenario."""

from __future__ import annotations

from parcover_env.envs.observations import ObservationLayout
from parcover_env.scenarios import load_scenario


def layout_of(box, max_speed: float, max_turn_rate: float, n_sonar: int, sonar_max: float, pred_range: float,
              covariance: bool = False) -> ObservationLayout:
    """The layout of the ``office`` scenario with these numbers (``n_sonar = 0``: sonar off)."""
    s = load_scenario("office", {
        "robot": {"max_speed": max_speed, "max_turn_rate": max_turn_rate,
                  "drive": {"wheel_speed_max": max_speed + 1.0},
                  "sonar": {"layout": "ring", "n_beams": max(n_sonar, 1), "range_max": sonar_max}},
        "formation": {"camera_range": pred_range},
        "observation": {"sonar": n_sonar > 0, "pose_covariance": covariance}})
    return ObservationLayout.build(s, box)
