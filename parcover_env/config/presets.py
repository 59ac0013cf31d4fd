"""Named presets: mapping transforms applied to a scenario before validation.

``realistic`` is the default and changes nothing: the schema's defaults are the realistic models.
``ideal`` switches every error source off (perfect odometry, instant velocity, ideal ray sonar,
noise-free Kinect) for unit tests that need exact numbers, and for ablations.

A preset is applied under the scenario's own values and the user's overrides win over both:
``load_scenario("office", overrides, preset="ideal")``.
"""

from __future__ import annotations

import copy
from collections.abc import Callable

from parcover_env.errors import ConfigError

__all__ = ["PRESETS", "apply_preset"]


def _realistic(data: dict) -> dict:
    return data


def _set(data: dict, path: tuple[str, ...], values: dict) -> None:
    """Set ``values`` in the nested mapping at ``path`` (created where missing)."""
    node = data
    for key in path:
        node = node.setdefault(key, {})
        if not isinstance(node, dict):
            return  # malformed: the schema will report it
    node.update(values)


def _ideal_sensors(data: dict) -> None:
    """Sonar and Kinect of the ``ideal`` preset: the sensor models as they were before the realism
    work, so that pinned rollouts reproduce bit for bit.

    Sonar: the ideal ray model unless the scenario names a model itself (``hallway`` and ``t_room``
    keep their cone-and-incidence ``specular`` model), never multipath nor cross-talk, echoes below
    ``range_min`` clipped (not lost). Range noise and quantization stay (they always were there).
    Kinect: a perfectly mounted camera (no extrinsic error) and no lateral noise; axial noise and
    disparity quantization stay."""
    robot = data.setdefault("robot", {})
    if isinstance(robot, dict):
        sonar = robot.setdefault("sonar", {})
        if isinstance(sonar, dict):
            sonar.setdefault("model", "ray")
            sonar.update({"multipath": False, "crosstalk_prob": 0.0, "below_min": "clip"})
    kinects = data.get("kinects")
    if isinstance(kinects, list):
        for k in kinects:
            if isinstance(k, dict):
                k.update(_IDEAL_KINECT)


_IDEAL_KINECT = {"mount_tilt_std_deg": 0.0, "mount_yaw_std_deg": 0.0, "mount_height_std": 0.0,
                 "lateral_noise_px": 0.0}
"""Kinect error fields the ``ideal`` preset switches off (see :class:`~parcover_env.config.KinectConfig`)."""


def _ideal(data: dict) -> dict:
    # Each error model registers its ideal values here (robot motion, odometry, sonar, Kinect).
    # Motion: commands act instantly; odometry measures the true motion with the pre-realism
    # per-step noise (the pinned rollouts' model; set noise_v = noise_omega = 0 for perfect odometry)
    # and the observation keeps the v0 layout (no covariance entries).
    _set(data, ("robot", "drive"), {"model": "instant"})
    _set(data, ("robot", "odometry"), {"model": "motion"})
    _set(data, ("observation",), {"pose_covariance": False})
    _ideal_sensors(data)
    return data


PRESETS: dict[str, Callable[[dict], dict]] = {"realistic": _realistic, "ideal": _ideal}


def apply_preset(data: object, preset: str, source: str = "") -> object:
    """``data`` (a parsed scenario mapping) with the named preset applied (input untouched)."""
    if preset not in PRESETS:
        raise ConfigError(source, "preset", f"unknown preset {preset!r}; choose from {', '.join(PRESETS)}")
    if not isinstance(data, dict):
        return data  # the schema reports the malformed top level
    return PRESETS[preset](copy.deepcopy(data))
