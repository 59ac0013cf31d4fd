"""The navigator's horizon (Kim, Pearce & Amato §3.1): stop before the uncertainty region hits a wall."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parcover_env.config import MapConfig, OdometryConfig
from parcover_env.expert.config import NavigatorConfig
from parcover_env.expert.horizon import RegionModel, collision_horizon, region_ellipse
from parcover_env.localization.sonar.subgoals import densify
from parcover_env.world.map_model import MapModel

R = 0.165
SIGMA_H = math.radians(2.0)
FIX = np.diag([0.05**2, 0.05**2, SIGMA_H**2])
QUIET = OdometryConfig(covariance_wheel_variance=0.0)  # no random wheel noise: the heading term alone


def _model(width: float) -> RegionModel:
    room = MapModel.from_config(MapConfig(size=(10.0, width)))
    return RegionModel(NavigatorConfig(), FIX, QUIET, 0.3, room, R)


def _horizon(width: float, x0: float = 0.5) -> float:
    path = densify([[x0, width / 2], [9.5, width / 2]], 0.05)
    return collision_horizon(path, 0.0, 9.0, FIX, 0.0, 0.0, 0.05, _model(width))


def test_region_ellipse_widens_the_covariance_ellipse_by_the_grown_axis():
    e = region_ellipse((1.0, 2.0), np.diag([0.04, 0.01, 0.0]), 0.3, 3.0)
    assert e.axes == pytest.approx((math.sqrt(9 * 0.04 + 0.09), math.sqrt(9 * 0.01 + 0.09)))


def test_horizon_ends_where_the_growing_region_first_leaves_the_corridor():
    """Driving straight along x from a fix (0.05 m, 2 deg), the lateral sigma is sqrt(0.05^2 +
    (0.0349 d)^2) and the seed B axis 0.05 + 0.05 d: the region's lateral semi-axis
    sqrt(9 sigma^2 + axis^2) reaches the centre's clearance (width / 2 - r) at
    0.0134662 d^2 + 0.005 d + 0.025 = (width / 2 - r)^2: d = 6.88 m in a 2 m corridor, 3.31 m in a
    1.2 m one. The horizon is the last node (every 0.05 m) before."""
    assert _horizon(2.0) == pytest.approx(6.85)
    assert _horizon(1.2) == pytest.approx(3.30)


def test_a_start_too_close_to_a_wall_for_any_region_does_not_end_the_horizon():
    """From x0 = 0.25 the centre's clearance to the end wall is 0.085 m, less than the region right
    after a fix (0.158 m): that collision is not caused by growth."""
    h = _horizon(2.0, x0=0.25)
    assert h == pytest.approx(6.85)
